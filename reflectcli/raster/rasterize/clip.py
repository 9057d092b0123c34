"""Clipping in homogeneous clip space (Sutherland-Hodgman against the near, far, extra and
guard-band planes) and the clip-space test that skips a whole run by its world box."""

import numpy as np
from numba import njit

from ...camera import screen_from_ndc as _screen_from_ndc
from .constants import _MAX_POLY

screen_from_ndc = njit(cache=True, inline="always")(_screen_from_ndc)


@njit(cache=True, inline="always")
def _clip_xyzw(m, x, y, z):
    x, y, z = np.float64(x), np.float64(y), np.float64(z)
    return (m[0, 0] * x + m[0, 1] * y + m[0, 2] * z + m[0, 3],
            m[1, 0] * x + m[1, 1] * y + m[1, 2] * z + m[1, 3],
            m[2, 0] * x + m[2, 1] * y + m[2, 2] * z + m[2, 3],
            m[3, 0] * x + m[3, 1] * y + m[3, 2] * z + m[3, 3])


@njit(cache=True, inline="always")
def _outside(planes, p, x, y, z, w):
    return planes[p, 0] * x + planes[p, 1] * y + planes[p, 2] * z + planes[p, 3] * w < 0.0


@njit(cache=True)
def _clip_polygon(corners, t, m, planes, width, height, out_xyw):
    """Clip triangle t against all planes; write its screen (x, y, 1/w) corners.

    Returns the vertex count of the clipped convex polygon (0 if nothing is left).
    """
    poly = np.empty((_MAX_POLY, 4))  # clip x, y, z, w
    nxt = np.empty((_MAX_POLY, 4))
    for k in range(3):
        x, y, z = corners[t, k, 0], corners[t, k, 1], corners[t, k, 2]
        for r in range(4):
            poly[k, r] = m[r, 0] * x + m[r, 1] * y + m[r, 2] * z + m[r, 3]
    n = 3
    for p in range(planes.shape[0]):
        count = 0
        for i in range(n):
            j = (i + 1) % n
            si = (planes[p, 0] * poly[i, 0] + planes[p, 1] * poly[i, 1]
                  + planes[p, 2] * poly[i, 2] + planes[p, 3] * poly[i, 3])
            sj = (planes[p, 0] * poly[j, 0] + planes[p, 1] * poly[j, 1]
                  + planes[p, 2] * poly[j, 2] + planes[p, 3] * poly[j, 3])
            if si >= 0.0:
                for q in range(4):
                    nxt[count, q] = poly[i, q]
                count += 1
            if (si >= 0.0) != (sj >= 0.0):
                a = si / (si - sj)
                for q in range(4):
                    nxt[count, q] = poly[i, q] + a * (poly[j, q] - poly[i, q])
                count += 1
        n = count
        for i in range(n):
            for q in range(4):
                poly[i, q] = nxt[i, q]
        if n < 3:
            return 0
    for i in range(n):
        iw = 1.0 / poly[i, 3]
        out_xyw[i, 0], out_xyw[i, 1] = screen_from_ndc(poly[i, 0] * iw, poly[i, 1] * iw, width,
                                                       height)
        out_xyw[i, 2] = iw
    return n




@njit(cache=True, error_model="numpy")
def _box_misses(bounds, chunk, m, planes, n_cut, width, height, col0, col1, top, bottom):
    """True if no triangle inside the world box bounds[chunk] can cover a pixel center of
    [top, bottom) x [col0, col1): its 8 corners all outside one side of the frustum or one
    of the first n_cut planes (a half-space is convex), or all in front of the eye (w > 0)
    and projecting, with a pixel to spare, beside the box (the projection of a convex set
    in front of the eye lies in the hull of its corners' projections)."""
    out = np.zeros(4 + n_cut, np.int64)
    in_front = True
    lo_x = lo_y = np.inf
    hi_x = hi_y = -np.inf
    for k in range(8):
        x = bounds[chunk, 3 if k & 1 else 0]
        y = bounds[chunk, 4 if k & 2 else 1]
        z = bounds[chunk, 5 if k & 4 else 2]
        cx, cy, cz, cw = _clip_xyzw(m, x, y, z)
        out[0] += cx < -cw
        out[1] += cx > cw
        out[2] += cy < -cw
        out[3] += cy > cw
        for p in range(n_cut):
            out[4 + p] += _outside(planes, p, cx, cy, cz, cw)
        if cw > 0.0:
            sx, sy = screen_from_ndc(cx / cw, cy / cw, width, height)
            lo_x, hi_x = min(lo_x, sx), max(hi_x, sx)
            lo_y, hi_y = min(lo_y, sy), max(hi_y, sy)
        else:
            in_front = False
    for q in range(4 + n_cut):
        if out[q] == 8:
            return True
    return in_front and (hi_x < col0 - 1.0 or lo_x > col1 + 1.0 or hi_y < top - 1.0
                         or lo_y > bottom + 1.0)

