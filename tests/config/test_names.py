"""Output names the file system cannot hold are refused by validate as by render: a name
over 255 bytes (UTF-8), a path over 4095 (config/names.py)."""

from __future__ import annotations

import pytest
from hardening.common import TINY, chdir, check_bad, invoke, write


@pytest.mark.parametrize(("section", "key", "value"), [
    ("scene", "name", "n" * 300),
    ("output", "log", "é" * 128),  # 128 characters, 256 bytes
    ("output", "log", "l" * 300),
    ("output", "dir", "out/" + "d" * 300 + "/x"),
])
def test_a_name_too_long_for_the_file_system(tmp_path, section, key, value):
    """300 characters validated ok; render then said 'File name too long' (a log rendered
    frame 0 first, then exited 1)."""
    text = (TINY.replace('name = "tiny"', f'name = "{value}"') if section == "scene"
            else TINY + f'\n[output]\n{key} = "{value}"\n')
    scene = write(tmp_path, "s.toml", text)
    with chdir(tmp_path):
        check_bad(scene, f"s.toml: {section}.{key}:", "255 bytes")


def test_a_path_too_long_for_the_file_system(tmp_path):
    deep = "/".join(["d" * 200] * 21)  # 4221 bytes, each name fine
    scene = write(tmp_path, "s.toml", TINY + f'\n[output]\ndir = "{deep}"\n')
    with chdir(tmp_path):
        check_bad(scene, "s.toml: output.dir:", "4095 bytes")


def test_names_at_the_limit_are_fine(tmp_path):
    scene = write(tmp_path, "s.toml", TINY.replace('name = "tiny"', f'name = "{"n" * 255}"')
                  + f'\n[output]\nlog = "{"é" * 127}"\n')
    with chdir(tmp_path):
        result = invoke("validate", scene)
    assert result.exit_code == 0, result.output
