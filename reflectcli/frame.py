"""A rendered frame: what every technique returns and every writer takes."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Frame:
    rgb: np.ndarray  # (H, W, 3) float32, linear
    depth: np.ndarray  # (H, W) float32, eye-space depth of the first hit, +inf on background
    surface: np.ndarray  # (H, W) int32, surface id of the first hit, -1 on background
    mirror_mask: np.ndarray  # (H, W) bool, first hit is a mirror
    extra: dict[str, np.ndarray] = field(default_factory=dict)  # lowercase EXR channels
    timings: dict[str, float] = field(default_factory=dict)  # stage -> seconds
    stats: dict[str, float | int] = field(default_factory=dict)  # counters for the log

    @property
    def alpha(self) -> np.ndarray:
        return (self.surface >= 0).astype(np.float32)
