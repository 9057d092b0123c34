"""The warp's arrays, kept across frames."""

from __future__ import annotations

import numpy as np

from .order import raster_runs
from .projection import Projection


class WarpBuffers:
    """The warp's per-frame arrays, kept across frames: page faults on fresh arrays cost more
    than the warp itself. Everything the warp writes into best_zd / best_id lies in `dirty`
    = (x0, x1, y0, y1), into out_z / out_id in `dirty_out`; a later use resets what it will
    not overwrite itself (outside them the buffers stay clear)."""

    def __init__(self, height: int, width: int) -> None:
        self.shape = (height, width)
        self.best_zd = np.full((height, width, 2), np.inf, np.float32)
        self.best_id = np.full((height, width), -1, np.int64)
        self.out_z = np.full((height, width), np.inf, np.float32)
        self.out_id = np.full((height, width), -1, np.int64)
        self.projections: dict[tuple[int, int], Projection] = {}
        self.radii: dict[tuple, np.ndarray] = {}
        self.runs: dict[tuple[int, int], np.ndarray] = {}
        self.dirty: tuple[int, int, int, int] | None = None
        self.dirty_out: tuple[int, int, int, int] | None = None

    def claim(self, region, written=None) -> None:
        """Reset best_zd / best_id where the last use wrote and `written` (the region the
        caller clears or overwrites itself, or None) does not cover; mark `region` dirty."""
        if self.dirty is not None and not _covers(written, self.dirty):
            x0, x1, y0, y1 = self.dirty
            self.best_zd[y0:y1, x0:x1] = np.inf
            self.best_id[y0:y1, x0:x1] = -1
        self.dirty = region

    def claim_out(self, box) -> None:
        """The same for out_z / out_id, which `spread` overwrites over `box`."""
        if self.dirty_out is not None and not _covers(box, self.dirty_out):
            x0, x1, y0, y1 = self.dirty_out
            self.out_z[y0:y1, x0:x1] = np.inf
            self.out_id[y0:y1, x0:x1] = -1
        self.dirty_out = box

    def projection(self, mh: int, mw: int) -> Projection:
        if (mh, mw) not in self.projections:
            self.projections[mh, mw] = Projection.empty(mh, mw)
        return self.projections[mh, mw]

    def fixed_radii(self, n: int, mode) -> np.ndarray:
        key = (n, str(mode))
        if key not in self.radii:
            self.radii[key] = (np.empty(n, np.int8) if mode == "adaptive"
                               else np.full(n, (int(mode) - 1) // 2, np.int8))
        return self.radii[key]

    def raster_runs(self, mh: int, mw: int) -> np.ndarray:
        if (mh, mw) not in self.runs:
            self.runs[mh, mw] = raster_runs(mh, mw)
        return self.runs[mh, mw]


def _covers(outer, inner) -> bool:
    """Box `outer` (x0, x1, y0, y1, or None) contains box `inner`."""
    return outer is not None and (outer[0] <= inner[0] and inner[1] <= outer[1]
                                  and outer[2] <= inner[2] and inner[3] <= outer[3])


def stencil_box(stencil: np.ndarray):
    """(rows holding a stencil pixel, (x0, x1, y0, y1) box) or (rows, None) if empty."""
    ys = np.flatnonzero(stencil.any(axis=1))
    if ys.size == 0:
        return ys, None
    xs = np.flatnonzero(stencil[ys[0]:ys[-1] + 1].any(axis=0))
    return ys, (int(xs[0]), int(xs[-1]) + 1, int(ys[0]), int(ys[-1]) + 1)


