"""Output names the file system can hold: checked with the scene, so that `validate` refuses
what `render` would fail on ("File name too long") instead of passing it, and a render never
fails on its log after writing its first frame."""

from __future__ import annotations

import os

NAME_MAX = 255  # bytes in one path component (Linux, macOS)
PATH_MAX = 4095  # bytes in a whole path (4096 with the terminating NUL)
# the longest name a render writes besides the log: a frame's temporary file while it is
# written (output/atomic.py), `.frame_99999.tmp<pid>-<thread id>.exr`
FILE_NAME_ROOM = 64


def _bytes(text: str) -> int:
    return len(os.fsencode(text))


def output_path_lengths(cfg, add) -> None:
    """Call add(loc, message) for an output name over NAME_MAX bytes (UTF-8) or output paths
    over PATH_MAX: out/<scene.name>/<technique>/<output.log or a frame>."""
    too_long = f"a name must be at most {NAME_MAX} bytes (UTF-8)"
    found = False
    for loc, names in ((("output", "dir"), cfg.output.dir.split(os.sep)),
                       (("scene", "name"), [cfg.scene.name]),
                       (("output", "log"), [cfg.output.log])):
        if any(_bytes(n) > NAME_MAX for n in names):
            add(loc, too_long)
            found = True
    if found:
        return
    technique = getattr(cfg.technique, "name", None) or "raytrace"
    longest = max(_bytes(cfg.output.log), FILE_NAME_ROOM)
    folder = os.path.join(os.path.abspath(cfg.output.dir), cfg.scene.name, technique)
    length = _bytes(folder) + 1 + longest
    if length > PATH_MAX:
        add(("output", "dir"), f"output paths would be {length} bytes long; a path must be at "
                               f"most {PATH_MAX} bytes")
