"""Temporal error over a camera path: how a technique's frame-to-frame change differs from
the reference's (flicker, and lag of temporal reuse or splats).

For consecutive frames t-1, t of the same selection, with test images T and reference R:
    e_t = RMSE over the mask of  (T_t - T_{t-1}) - (R_t - R_{t-1})
(which is also the change of the error image T - R from one frame to the next). A technique
that is wrong the same way on every frame has no temporal error; one that flickers or
lags has. The mask of frame t is the caller's (the mirror in both images, both frames).
The total is the RMSE over all frames' masked pixels (sqrt of the pixel-weighted mean of
e_t^2). A single frame has no temporal error (empty lists, total NaN).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def temporal_errors(test: Sequence[np.ndarray], reference: Sequence[np.ndarray],
                    masks: Sequence[np.ndarray | None] | None = None
                    ) -> tuple[list[float], float]:
    """(per-frame errors for frames 1..n-1, total). `masks[t]` restricts frame t's pair
    (t-1, t); None or a missing list means every pixel."""
    if len(test) != len(reference):
        raise ValueError(f"{len(test)} test frames against {len(reference)} reference frames")
    per_frame: list[float] = []
    sq_sum, count = 0.0, 0
    for t in range(1, len(test)):
        change = (np.asarray(test[t], np.float64) - np.asarray(test[t - 1], np.float64)) - (
            np.asarray(reference[t], np.float64) - np.asarray(reference[t - 1], np.float64))
        mask = masks[t] if masks is not None else None
        values = change[mask] if mask is not None else change.reshape(-1, *change.shape[2:])
        if values.size == 0:
            per_frame.append(math.nan)
            continue
        sq = float(np.sum(values**2))
        per_frame.append(math.sqrt(sq / values.size))
        sq_sum += sq
        count += values.size
    total = math.sqrt(sq_sum / count) if count else math.nan
    return per_frame, total
