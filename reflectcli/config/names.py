"""Output names the file system can hold: checked with the scene, so that `validate` refuses
what `render` would fail on ("File name too long") instead of passing it, and a render never
fails on its log after writing its first frame."""

from __future__ import annotations

import os

NAME_MAX = 255  # bytes in one path component (Linux, macOS)
NAME_PATTERN = r"^[A-Za-z0-9._-]+$"  # a scene's or bench's name: its output folder's name
PATH_MAX = 4095  # bytes in a whole path (4096 with the terminating NUL)
# the longest name a render writes besides the log: a frame's temporary file while it is
# written (output/atomic.py), `.frame_99999.tmp<pid>-<thread id>.exr`
FILE_NAME_ROOM = 64


def _bytes(text: str) -> int:
    return len(os.fsencode(text))


def output_path_lengths(cfg, add) -> None:
    """Call add(loc, message) for a scene name or log name over NAME_MAX bytes (UTF-8): they
    are in every output path. The output folder's own names and the whole path's length are
    the root's (`root_length_problem`), checked where the root is known: `--out` replaces
    `output.dir`."""
    too_long = f"a name must be at most {NAME_MAX} bytes (UTF-8)"
    for loc, name in ((("scene", "name"), cfg.scene.name), (("output", "log"), cfg.output.log)):
        if _bytes(name) > NAME_MAX:
            add(loc, too_long)


def root_length_problem(root: str, scene: str, technique: str, log: str) -> str | None:
    """Why output paths under `root` (the output folder a render uses: `--out` or
    `output.dir`) would be too long for the file system: a folder name over NAME_MAX bytes,
    or root/<scene>/<technique>/<log or a frame's temporary file> over PATH_MAX; else None.
    `scene` and `log` are checked by output_path_lengths."""
    if any(_bytes(n) > NAME_MAX for n in root.split(os.sep)):
        return f"a name must be at most {NAME_MAX} bytes (UTF-8)"
    longest = max(_bytes(log), FILE_NAME_ROOM)
    folder = os.path.join(os.path.abspath(root), scene, technique)
    length = _bytes(folder) + 1 + longest
    if length > PATH_MAX:
        return (f"output paths would be {length} bytes long; a path must be at most "
                f"{PATH_MAX} bytes")
    return None
