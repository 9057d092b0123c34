"""Where and how frames are written."""

from __future__ import annotations

from .base import Strict


class OutputConfig(Strict):
    dir: str = "out"  # relative to the working directory; out/<scene>/<technique>/frame_0000.exr
    preview: bool = False  # also write an sRGB PNG beside each EXR
    log: str = "timings.jsonl"  # JSON lines, one per frame, beside the frames
