"""World boxes of runs of triangles, for the rasterizer's run skipping (numba): numpy's
min / max over the middle axis of (runs, 768, 3) float32 took milliseconds a call, and
passes over freshly made triangles (virtual objects) need them every call."""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, parallel=True)
def run_bounds(corners, run, bounds):
    """bounds[c] = (min x, y, z, max x, y, z) (world) of corners (T, 3, 3) of triangles
    c * run .. c * run + run - 1 (the last run may be short): the same values as numpy's
    min / max (a minimum of float32 values is one of them, exactly; NaN where a value is
    NaN, as numpy gives)."""
    n = corners.shape[0]
    for c in prange(bounds.shape[0]):
        t0 = c * run
        t1 = min(n, t0 + run)
        for q in range(3):
            lo = corners[t0, 0, q]
            hi = lo
            nan = False
            for t in range(t0, t1):
                for k in range(3):
                    v = corners[t, k, q]
                    lo = min(lo, v)
                    hi = max(hi, v)
                    nan |= v != v
            bounds[c, q] = np.nan if nan else lo
            bounds[c, 3 + q] = np.nan if nan else hi
