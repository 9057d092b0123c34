"""The fixed-point screen grid: corners snapped to 2^-S pixel, so edge functions are exact
int64 (no rounding decides coverage)."""

import numpy as np
from numba import njit

# fixed-point corners stay within +-2^_FIXED_BITS: edge functions (products of two corner
# differences, summed) then stay below 2^62 in int64
_FIXED_BITS = 29


def _subpixel_bits(width: int, height: int) -> tuple[int, float]:
    """(S, guard): corners are snapped to 2^-S pixel and kept (by clipping) within `guard`
    pixels beyond each side of the screen, so every snapped coordinate is below
    2^_FIXED_BITS in magnitude."""
    span = 1 << int(np.ceil(np.log2(2 * max(width, height, 2))))  # >= 2 * the screen
    bits = _FIXED_BITS - int(np.log2(span))
    return bits, 0.45 * span


def guarded_planes(planes: np.ndarray, width: int, height: int) -> tuple[np.ndarray, int]:
    """(the clip-space planes followed by the guard band's four, subpixel bits S): what a
    draw's setup tests corners against. The band keeps x_ndc in [-gx, gx] and y_ndc in
    [-gy, gy] (clip x + gx w >= 0, ...), `_subpixel_bits`' guard pixels past each side."""
    planes = np.asarray(planes)
    key = (planes.dtype.str, planes.shape, planes.tobytes(), width, height)
    made = _GUARDED.get(key)
    if made is None:  # made once per planes and size (50 us between a frame's kernels)
        bits, guard = _subpixel_bits(width, height)
        gx, gy = 1.0 + 2.0 * guard / width, 1.0 + 2.0 * guard / height
        band = np.array([[1.0, 0, 0, gx], [-1.0, 0, 0, gx], [0, 1.0, 0, gy],
                         [0, -1.0, 0, gy]])
        if len(_GUARDED) >= 64:
            _GUARDED.clear()
        made = _GUARDED[key] = (np.ascontiguousarray(np.vstack([planes, band])), bits)
    return made[0].copy(), made[1]


_GUARDED: dict[tuple, tuple[np.ndarray, int]] = {}  # guarded_planes', by their arguments



@njit(cache=True, inline="always")
def _snap(v, scale):
    """A screen coordinate in units of 1/scale pixel, rounded to nearest (halves up).

    Converted through int32, exact: every coordinate snapped is inside the guard band, so
    below 2^_FIXED_BITS in magnitude (float64 -> int64 has no AVX2 instruction: the
    vectorised snap of a run converted one lane at a time, 2.5 of its 18 ms at 1M
    triangles)."""
    return np.int64(np.int32(np.floor(v * scale + 0.5)))
