"""World points to screen pixels, for seeding searches on a reflector's pixels."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..camera import screen_from_ndc
from ..fused import fma

_screen_from_ndc = njit(cache=True, inline="always")(screen_from_ndc)


def screen_from_world(points: np.ndarray, clip_from_world: np.ndarray, width: int,
                      height: int) -> np.ndarray:
    """(N, 3): screen x, y (pixels, y down) and eye depth w (the clip w, <= 0 behind the
    eye) of world points (N, 3)."""
    out = np.empty((len(points), 3))
    _screen_rows(np.ascontiguousarray(points, np.float64),
                 np.ascontiguousarray(clip_from_world, np.float64), width, height, out)
    return out


@njit(cache=True, error_model="numpy")
def _screen_rows(points, clip_from_world, width, height, out):
    """screen_from_world's rows, each as numpy's `points @ m[:3, :3].T + m[:3, 3]` and
    `points @ m[3, :3] + m[3, 3]` make it on this machine kind (OpenBLAS: a row of a matrix
    product as fma(p2, m2, fma(p1, m1, p0 m0)), a matrix-vector product as fma(p2, m2,
    fma(p0, m0, p1 m1)); a single row, which numpy takes as a matrix-vector product and a
    dot product, as fma(p2, m2, fma(p0, m0, p1 m1)) and (p0 m0 + p1 m1) + p2 m2), then
    divided and mapped as screen_from_ndc: the same bits (elsewhere within rounding of
    them), without numpy's dozen calls (70 us on a few hundred points, 28 calls a mask
    frame). A row's answer so depends on whether it is projected alone."""
    m = clip_from_world
    one = points.shape[0] == 1
    for i in range(points.shape[0]):
        p0, p1, p2 = points[i, 0], points[i, 1], points[i, 2]
        if one:  # numpy takes one row by other routes: a matrix-vector product, a dot
            x = fma(p2, m[0, 2], fma(p0, m[0, 0], p1 * m[0, 1])) + m[0, 3]
            y = fma(p2, m[1, 2], fma(p0, m[1, 0], p1 * m[1, 1])) + m[1, 3]
            w = (p0 * m[3, 0] + p1 * m[3, 1]) + p2 * m[3, 2] + m[3, 3]
        else:
            x = fma(p2, m[0, 2], fma(p1, m[0, 1], p0 * m[0, 0])) + m[0, 3]  # clip
            y = fma(p2, m[1, 2], fma(p1, m[1, 1], p0 * m[1, 0])) + m[1, 3]
            w = fma(p2, m[3, 2], fma(p0, m[3, 0], p1 * m[3, 1])) + m[3, 3]
        out[i, 0], out[i, 1] = _screen_from_ndc(x / w, y / w, width, height)  # NDC -> screen
        out[i, 2] = w
