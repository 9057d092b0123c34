"""The names reflect writes in a frame folder, in one place: output.log is checked against
them (config/limits.py), so that no output can replace another, and the folder is checked
for links at them before a render (paths.check_links)."""

from __future__ import annotations

import re

SUMMARY_NAME = "timings-summary.json"
LOCK_NAME = ".reflect.lock"
FRAME = re.compile(r"^frame_\d+\.(exr|png)$")


def taken_by(name: str) -> str | None:
    """What else reflect writes under `name` in a frame folder (None: nothing). Compared
    without case: on a case-insensitive disk `Timings-Summary.json` is the summary."""
    folded = name.casefold()
    if folded == SUMMARY_NAME:
        return f"the timings summary ({SUMMARY_NAME})"
    if folded == LOCK_NAME:
        return f"the folder lock ({LOCK_NAME})"
    if FRAME.match(folded) or folded.endswith((".exr", ".png")):
        return "a frame (.exr or .png)"
    return None
