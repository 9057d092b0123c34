"""World points to screen pixels, for seeding searches on a reflector's pixels."""

from __future__ import annotations

import numpy as np

from ..camera import screen_from_ndc


def screen_from_world(points: np.ndarray, clip_from_world: np.ndarray, width: int,
                      height: int) -> np.ndarray:
    """(N, 3): screen x, y (pixels, y down) and eye depth w (the clip w, <= 0 behind the
    eye) of world points (N, 3)."""
    h = points @ clip_from_world[:3, :3].T + clip_from_world[:3, 3]  # clip x, y, z
    w = points @ clip_from_world[3, :3] + clip_from_world[3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        x, y = screen_from_ndc(h[:, 0] / w, h[:, 1] / w, width, height)
    return np.stack([x, y, w], axis=1)
