"""Output names the file system cannot hold are refused by validate as by render: a name
over 255 bytes (UTF-8), a path over 4095 (config/names.py); the output folder's, of the folder
a render uses (`--out` replaces `output.dir`)."""

from __future__ import annotations

import pytest
from hardening.common import TINY, assert_one_line, chdir, check_bad, files_under, invoke, write

LONG_DIR = "out/" + "d" * 300 + "/x"
DEEP_DIR = "/".join(["d" * 200] * 21)  # 4221 bytes, each name fine


@pytest.mark.parametrize(("section", "key", "value"), [
    ("scene", "name", "n" * 300),
    ("output", "log", "é" * 128),  # 128 characters, 256 bytes
    ("output", "log", "l" * 300),
])
def test_a_name_too_long_for_the_file_system(tmp_path, section, key, value):
    """300 characters validated ok; render then said 'File name too long' (a log rendered
    frame 0 first, then exited 1)."""
    text = (TINY.replace('name = "tiny"', f'name = "{value}"') if section == "scene"
            else TINY + f'\n[output]\n{key} = "{value}"\n')
    scene = write(tmp_path, "s.toml", text)
    with chdir(tmp_path):
        check_bad(scene, f"s.toml: {section}.{key}:", "255 bytes")


def _check_bad_output_dir(tmp_path, *needles: str) -> None:
    """validate and a render into output.dir refuse s.toml in the same line, writing
    nothing; a render given --out (output.dir unused) is not refused for it."""
    scene = tmp_path / "s.toml"
    before = files_under(tmp_path)
    with chdir(tmp_path):
        line = assert_one_line(invoke("validate", scene), *needles)
        assert assert_one_line(invoke("render", scene, "--frames", "0"), *needles) == line
        assert files_under(tmp_path) == before
        result = invoke("render", scene, "--out", "o", "--frames", "0")
    assert result.exit_code == 0, result.output
    assert (tmp_path / "o" / "tiny" / "raytrace" / "frame_0000.exr").exists()


@pytest.mark.parametrize(("value", "needle"), [(LONG_DIR, "255 bytes"),
                                               (DEEP_DIR, "4095 bytes")])
def test_an_output_dir_too_long_for_the_file_system(tmp_path, value, needle):
    """`render --out o` was refused for the output.dir it does not use."""
    write(tmp_path, "s.toml", TINY + f'\n[output]\ndir = "{value}"\n')
    _check_bad_output_dir(tmp_path, "s.toml: output.dir:", needle)


def test_an_output_dir_too_long_is_named_in_the_file_it_came_from(tmp_path):
    write(tmp_path, "out.toml", f'[output]\ndir = "{LONG_DIR}"\n')
    write(tmp_path, "s.toml", 'include = ["out.toml"]\n' + TINY)
    _check_bad_output_dir(tmp_path, "out.toml: output.dir:", "255 bytes")


@pytest.mark.parametrize(("value", "needle"), [(LONG_DIR, "255 bytes"),
                                               (DEEP_DIR, "4095 bytes")])
def test_an_out_too_long_for_the_file_system(tmp_path, value, needle):
    """--out is held to the limits output.dir is: render said 'File name too long' after
    making the folders it could."""
    scene = write(tmp_path, "s.toml", TINY)
    with chdir(tmp_path):
        assert_one_line(invoke("render", scene, "--out", value, "--frames", "0"),
                        "--out: ", needle)
    assert files_under(tmp_path) == [str(scene)]


def test_names_at_the_limit_are_fine(tmp_path):
    scene = write(tmp_path, "s.toml", TINY.replace('name = "tiny"', f'name = "{"n" * 255}"')
                  + f'\n[output]\nlog = "{"é" * 127}"\n')
    with chdir(tmp_path):
        result = invoke("validate", scene)
    assert result.exit_code == 0, result.output
