"""Camera paths whose frames, not keys, are degenerate: every frame is checked by validate and
render alike (one line naming camera.path and the frame), not rendered blank or to a
traceback."""

from __future__ import annotations

import pytest

from .common import TINY, chdir, check_bad, write

PATHS = [  # (the [camera.path] table, what its line says)
    # key 0's eye is its target: a blank frame and numpy's RuntimeWarning on stderr
    ('frames = 3\nkeys = [{ eye = [0, 1, 3], target = [0, 1, 3] },\n'
     '        { eye = [0, 1, 3], target = [0, 0.5, 0] }]\n',
     "eye and target coincide at frame 0"),
    # eye and target swap places: they meet at frame 1
    ('frames = 3\ninterpolation = "linear"\n'
     'keys = [{ eye = [0, 1, 3], target = [0, 0.5, 0] },\n'
     '        { eye = [0, 0.5, 0], target = [0, 1, 3] }]\n',
     "eye and target coincide at frame 1"),
    # opposite ups cancel halfway: a traceback (NaN to integer) in the rasterizer
    ('frames = 3\ninterpolation = "linear"\n'
     'keys = [{ eye = [0, 1, 3], target = [0, 0.5, 0], up = [0, 1, 0] },\n'
     '        { eye = [0, 1, 3], target = [0, 0.5, 0], up = [0, -1, 0] }]\n',
     "up is zero or parallel to the viewing direction at frame 1"),
    # Catmull-Rom overshoots below the keys' fovs: frame 6 rendered with fov_y -9 degrees
    ('frames = 11\n'
     'keys = [{ eye = [0, 1, 3], target = [0, 0.5, 0], fov_y = 160 },\n'
     '        { eye = [0, 1, 3.1], target = [0, 0.5, 0], fov_y = 1 },\n'
     '        { eye = [0, 1, 3.2], target = [0, 0.5, 0], fov_y = 1 }]\n',
     "fov_y is -9.18 degrees (must be 0.01..170) at frame 6"),
]


@pytest.mark.parametrize(("path", "said"), PATHS)
def test_a_degenerate_frame_of_a_path_is_one_line(tmp_path, path, said):
    scene = write(tmp_path, "s.toml", TINY.replace("height = 12\n",
                                                   "height = 12\n[camera.path]\n" + path))
    with chdir(tmp_path):
        check_bad(scene, f"s.toml: camera.path: {said}")


def test_a_sound_path_still_renders(tmp_path):
    from .common import invoke

    path = ('[camera.path]\nframes = 3\nkeys = [{ eye = [0, 1, 3], target = [0, 0.5, 0] },\n'
            '        { eye = [1, 1, 3], target = [0, 0.5, 0], up = [0, 1, 0.1] }]\n')
    scene = write(tmp_path, "s.toml", TINY.replace("height = 12\n", "height = 12\n" + path))
    with chdir(tmp_path):
        assert invoke("validate", scene).output.strip() == "ok"
