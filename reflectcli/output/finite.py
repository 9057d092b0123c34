"""The last guard before a file is written: nothing non-finite reaches an output file.

Z may be +inf (background, by design); every other value must be finite."""

from __future__ import annotations

import numpy as np

from ..errors import Problem, Problems


def check_finite(channels: dict, source: str, frame_index: int) -> None:
    for name, values in channels.items():
        values = np.asarray(values)
        bad = np.isnan(values) if name == "Z" else ~np.isfinite(values)
        if bad.any():
            message = (f"frame {frame_index}: channel {name} has {int(bad.sum())} non-finite "
                       "value(s) (degenerate input?); nothing written for this frame")
            raise Problems([Problem(source, "", message)])
