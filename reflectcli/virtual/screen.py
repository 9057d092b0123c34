"""World points to screen pixels, for seeding searches on a reflector's pixels."""

from __future__ import annotations

import numpy as np


def screen_from_world(points: np.ndarray, clip_from_world: np.ndarray, width: int,
                      height: int) -> np.ndarray:
    """(N, 3): screen x, y (pixels, y down) and eye depth w (the clip w, <= 0 behind the
    eye) of world points (N, 3)."""
    h = points @ clip_from_world[:3, :3].T + clip_from_world[:3, 3]  # clip x, y, z
    w = points @ clip_from_world[3, :3] + clip_from_world[3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        # NDC -> screen
        x = (h[:, 0] / w + 1.0) * 0.5 * width
        y = (1.0 - h[:, 1] / w) * 0.5 * height
    return np.stack([x, y, w], axis=1)
