"""--frames (and a bench file's frames) in the documented syntax only: N, A:B, A:B:S with
ASCII digits. int() also took '1_0' (frame 10), ' 3 ' and other scripts' digits ('٣', frame
3), so a typo rendered frames nobody asked for."""

from __future__ import annotations

import pytest

from reflectcli.api import parse_frames
from reflectcli.errors import Problems

from .common import TINY, assert_one_line, chdir, files_under, invoke, write

PATH = ('[camera.path]\nframes = 12\n'
        'keys = [{ eye = [0, 1, 3], target = [0, 0.5, 0] }, '
        '{ eye = [1, 1, 3], target = [0, 0.5, 0] }]\n')


@pytest.mark.parametrize("spec", ["1_0", "\u0663", " 3", "3 ", "0:1_0", "0:\u0663", "0:4:\u0661",
                                  "+3", "0x3", ""])
def test_frames_outside_the_syntax_are_refused(spec):
    with pytest.raises(Problems, match="expected N, A:B or A:B:S"):
        parse_frames(spec, 12)


@pytest.mark.parametrize(("spec", "frames"), [
    ("3", [3]), ("0:3", [0, 1, 2]), ("8:", [8, 9, 10, 11]), (":2", [0, 1]),
    ("0:12:5", [0, 5, 10]), ("::6", [0, 6]), ("0:99", list(range(12))),
])
def test_frames_in_the_syntax(spec, frames):
    assert list(parse_frames(spec, 12)) == frames


def test_frames_typo_on_the_command_line_is_one_line(tmp_path):
    scene = write(tmp_path, "s.toml", TINY.replace("height = 12\n", "height = 12\n" + PATH))
    with chdir(tmp_path):
        result = invoke("render", scene, "--out", tmp_path / "o", "--frames", "1_0")
    assert_one_line(result, "--frames: expected N, A:B or A:B:S, got '1_0'")
    assert files_under(tmp_path / "o") == []
