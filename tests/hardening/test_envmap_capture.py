"""A correct envmap `capture` table renders (it was checked against the warm-up scene)."""

from __future__ import annotations

from .common import TINY, chdir, invoke, write


def test_capture_table_naming_a_real_mirror_renders(tmp_path):
    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "envmap"\nresolution = 8\n'
                  '[technique.capture]\nfloor = [0.0, 0.1, 0.0]\n')
    with chdir(tmp_path):
        result = invoke("render", scene, "--out", tmp_path / "out", "--frames", "0",
                        "--cache", tmp_path / "cache")
    assert result.exit_code == 0, result.output
    assert "warm-up" not in result.output
    assert (tmp_path / "out" / "tiny" / "envmap" / "frame_0000.exr").exists()


def test_capture_naming_no_mirror_is_refused_by_validate_and_render(tmp_path):
    from .common import check_bad

    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "envmap"\nresolution = 8\n'
                  '[technique.capture]\nflor = [0.0, 0.1, 0.0]\n')
    with chdir(tmp_path):
        check_bad(scene, "s.toml: technique.capture.flor: no mirror of that name")
