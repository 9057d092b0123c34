"""Triangle setup: per snapped screen triangle its culling, box, edge functions (top-left
rule) and key plane (`_setup`), and the setup of a whole run in vectorised loops
(`_run_setup`)."""

import numpy as np
from numba import njit

from ...scene.types import MIRROR_TIE
from .clip import screen_from_ndc
from .constants import (
    _CHUNK,
    _CLIPPED,
    _CULLED,
    _SIMPLE,
    CULL_BACK,
    CULL_FRONT,
    FLAG_MIRROR,
    FLAG_SKIP,
)
from .fixed import _snap


@njit(cache=True, inline="always")
def _setup(x0, y0, w0, x1, y1, w1, x2, y2, w2, key_scale, cull, bits, top, bottom, col0, col1):
    """Triangle setup of one snapped screen triangle (corners in units of 2^-bits pixel,
    int64; w0..w2 their 1/w) for `_rows`, written without branches (a run's setups are one
    vectorised loop). Returns (drawn, xs, n, ys, ye, first_y, e0, e1, e2, sa0, sa1, sa2, sb0,
    sb1, sb2, z_ref, dzdx, dzdy, zx0): drawn is False for a culled or degenerate triangle,
    one whose pixel centers all miss the box [top, bottom) x [col0, col1), or one whose
    corners' box holds at most 2 x 2 centers, none inside; the edge functions at the center
    of pixel (xs, ys) with their biases, their steps along a row and down a column; the key
    plane as `_rows` evaluates it (meaningless where drawn is False)."""
    area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    # screen y points down: a counter-clockwise (front) triangle has negative area here
    facing = ((area != 0) & ((cull != CULL_BACK) | (area < 0))
              & ((cull != CULL_FRONT) | (area > 0)))
    # wind every triangle one way: inside is then where all edges are >= 0
    flip = area < 0
    x1, x2 = (x2, x1) if flip else (x1, x2)
    y1, y2 = (y2, y1) if flip else (y1, y2)
    w1, w2 = (w2, w1) if flip else (w1, w2)
    area = -area if flip else area
    one = np.int64(1)
    half = one << (bits - 1)
    first_x = -((half - min(x0, x1, x2)) >> bits)  # pixel centers inside the corners' box
    last_x = (max(x0, x1, x2) - half) >> bits
    first_y = -((half - min(y0, y1, y2)) >> bits)
    last_y = (max(y0, y1, y2) - half) >> bits
    xs = max(first_x, col0)
    xe = min(last_x, col1 - 1)
    ys = max(first_y, top)
    ye = min(last_y, bottom - 1)
    # edge k is opposite corner k: e_k(P) = a_k (Px - xa) + b_k (Py - ya) over edge a -> b
    a0, b0 = y1 - y2, x2 - x1
    a1, b1 = y2 - y0, x0 - x2
    a2, b2 = y0 - y1, x1 - x0
    # top-left rule: an edge owns the centers on it when its inward normal (a, b) points
    # right, or straight down; elsewhere a center must be strictly inside (e >= 1)
    bias0 = np.int64(0) if (a0 > 0) | ((a0 == 0) & (b0 > 0)) else np.int64(-1)
    bias1 = np.int64(0) if (a1 > 0) | ((a1 == 0) & (b1 > 0)) else np.int64(-1)
    bias2 = np.int64(0) if (a2 > 0) | ((a2 == 0) & (b2 > 0)) else np.int64(-1)
    px0 = (xs << bits) + half
    py0 = (ys << bits) + half
    e0 = a0 * (px0 - x1) + b0 * (py0 - y1) + bias0
    e1 = a1 * (px0 - x2) + b1 * (py0 - y2) + bias1
    e2 = a2 * (px0 - x0) + b2 * (py0 - y0) + bias2
    sa0, sa1, sa2 = a0 << bits, a1 << bits, a2 << bits
    sb0, sb1, sb2 = b0 << bits, b1 << bits, b2 << bits
    # a box of at most 2 x 2 centers (most small triangles) is tested here whole
    wide, tall = xe > xs, ye > ys
    covered = (((xe - xs) > 1) | ((ye - ys) > 1) | ((e0 | e1 | e2) >= 0)
               | (wide & (((e0 + sa0) | (e1 + sa1) | (e2 + sa2)) >= 0))
               | (tall & (((e0 + sb0) | (e1 + sb1) | (e2 + sb2)) >= 0))
               | (wide & tall & (((e0 + sa0 + sb0) | (e1 + sa1 + sb1)
                                  | (e2 + sa2 + sb2)) >= 0)))
    drawn = facing & (xs <= xe) & (ys <= ye) & covered
    # 1/w is affine in screen space: the plane through the corners, stepped from the
    # (unclamped) box corner, so a pixel's key depends on the triangle and pixel only
    # (a degenerate triangle is never drawn; dividing by 1 keeps the interpreted twin run
    # of this branch-free code, under NUMBA_DISABLE_JIT, from raising)
    inv_area = key_scale / float(area + (area == 0))
    sx = float(one << bits)
    dzdx = (a0 * w0 + a1 * w1 + a2 * w2) * sx * inv_area
    dzdy = (b0 * w0 + b1 * w1 + b2 * w2) * sx * inv_area
    cx = (first_x << bits) + half
    cy = (first_y << bits) + half
    z_ref = ((a0 * (cx - x1) + b0 * (cy - y1)) * w0 + (a1 * (cx - x2) + b1 * (cy - y2)) * w1
             + (a2 * (cx - x0) + b2 * (cy - y0)) * w2) * inv_area
    return (drawn, xs, xe - xs + 1, ys, ye, first_y, e0, e1, e2, sa0, sa1, sa2, sb0, sb1,
            sb2, z_ref, dzdx, dzdy, dzdx * (xs - first_x))



@njit(cache=True, error_model="numpy")
def _run_setup(corners, flags, m, planes, n_cut, width, height, bits, scale, cull, top,
               bottom, col0, col1, t0, count, soa, clip, ints, floats, status):
    """Setup of triangles t0 .. t0 + count - 1 (j = t - t0), in loops over the run without
    branches (vectorised): their corners' clip coordinates, status[j] _CULLED (outside one
    side of the frustum or one of the first n_cut planes, or FLAG_SKIP), _CLIPPED (a plane
    cuts it, or it leaves the guard band) or _SIMPLE, and for a simple one its corners'
    snapped screen x, y (`snapped` rows 2k, 2k + 1) and 1/w (`inv_w` row k), the very
    values (same operations, same order) as a scalar loop per triangle would give.
    `soa`, `clip`: scratch, (9, n) corners and (12, n) clip x, y, z, w per corner."""
    # the run's flags through a view indexed from 0 (flags[t0 + j] pays numba's
    # negative-index wraparound in every vectorised loop that reads it: 10% of the setup)
    run_flags = flags[t0:t0 + count]
    for j in range(count):
        for k in range(3):
            for q in range(3):
                soa[3 * k + q, j] = corners[t0 + j, k, q]
    m00, m01, m02, m03 = m[0, 0], m[0, 1], m[0, 2], m[0, 3]
    m10, m11, m12, m13 = m[1, 0], m[1, 1], m[1, 2], m[1, 3]
    m20, m21, m22, m23 = m[2, 0], m[2, 1], m[2, 2], m[2, 3]
    m30, m31, m32, m33 = m[3, 0], m[3, 1], m[3, 2], m[3, 3]
    for k in range(3):
        for j in range(count):
            x = np.float64(soa[3 * k, j])
            y = np.float64(soa[3 * k + 1, j])
            z = np.float64(soa[3 * k + 2, j])
            clip[4 * k, j] = m00 * x + m01 * y + m02 * z + m03
            clip[4 * k + 1, j] = m10 * x + m11 * y + m12 * z + m13
            clip[4 * k + 2, j] = m20 * x + m21 * y + m22 * z + m23
            clip[4 * k + 3, j] = m30 * x + m31 * y + m32 * z + m33
    # status so far: 0 culled, 1 simple, 2 cut (by the guard band: screen coordinates
    # beyond it could overflow the fixed-point range)
    gx = planes[n_cut, 3]
    gy = planes[n_cut + 2, 3]
    for j in range(count):
        x0, y0, w0 = clip[0, j], clip[1, j], clip[3, j]
        x1, y1, w1 = clip[4, j], clip[5, j], clip[7, j]
        x2, y2, w2 = clip[8, j], clip[9, j], clip[11, j]
        out = (((x0 < -w0) & (x1 < -w1) & (x2 < -w2)) | ((x0 > w0) & (x1 > w1) & (x2 > w2))
               | ((y0 < -w0) & (y1 < -w1) & (y2 < -w2)) | ((y0 > w0) & (y1 > w1) & (y2 > w2))
               | ((run_flags[j] & FLAG_SKIP) != 0))
        cut = ((abs(x0) > gx * w0) | (abs(x1) > gx * w1) | (abs(x2) > gx * w2)
               | (abs(y0) > gy * w0) | (abs(y1) > gy * w1) | (abs(y2) > gy * w2))
        status[j] = _CULLED if out else (_CLIPPED if cut else _SIMPLE)
    for p in range(n_cut):
        a, b, c, d = planes[p, 0], planes[p, 1], planes[p, 2], planes[p, 3]
        for j in range(count):
            o0 = a * clip[0, j] + b * clip[1, j] + c * clip[2, j] + d * clip[3, j] < 0.0
            o1 = a * clip[4, j] + b * clip[5, j] + c * clip[6, j] + d * clip[7, j] < 0.0
            o2 = a * clip[8, j] + b * clip[9, j] + c * clip[10, j] + d * clip[11, j] < 0.0
            s = status[j]
            status[j] = _CULLED if (o0 & o1 & o2) | (s == _CULLED) else (
                _CLIPPED if o0 | o1 | o2 else s)
    for k in range(3):
        for j in range(count):
            simple = status[j] == _SIMPLE
            # only a simple triangle's corners are used (and safe to snap)
            w = clip[4 * k + 3, j] if simple else 1.0
            iw = 1.0 / w
            sx, sy = screen_from_ndc(clip[4 * k, j] * iw, clip[4 * k + 1, j] * iw, width,
                                     height)
            sx = sx if simple else 0.0
            sy = sy if simple else 0.0
            ints[2 * k * _CHUNK + j] = _snap(sx, scale)
            ints[(2 * k + 1) * _CHUNK + j] = _snap(sy, scale)
            floats[k * _CHUNK + j] = iw
    # the setups of the simple triangles (the others' are meaningless), their keep flag
    # in row 20: drawn, see _setup (one array for the ints, one for the floats, rows a
    # constant _CHUNK apart: the compiler sees they never overlap)
    c = _CHUNK
    for j in range(count):
        q = _setup(ints[j], ints[c + j], floats[j], ints[2 * c + j], ints[3 * c + j],
                   floats[c + j], ints[4 * c + j], ints[5 * c + j], floats[2 * c + j],
                   1.0 / MIRROR_TIE if run_flags[j] & FLAG_MIRROR else 1.0, cull, bits, top,
                   bottom, col0, col1)
        ints[20 * c + j] = q[0] & (status[j] == _SIMPLE)
        ints[6 * c + j] = q[1]
        ints[7 * c + j] = q[2]
        ints[8 * c + j] = q[3]
        ints[9 * c + j] = q[4]
        ints[10 * c + j] = q[5]
        ints[11 * c + j] = q[6]
        ints[12 * c + j] = q[7]
        ints[13 * c + j] = q[8]
        ints[14 * c + j] = q[9]
        ints[15 * c + j] = q[10]
        ints[16 * c + j] = q[11]
        ints[17 * c + j] = q[12]
        ints[18 * c + j] = q[13]
        ints[19 * c + j] = q[14]
        floats[3 * c + j] = q[15]
        floats[4 * c + j] = q[16]
        floats[5 * c + j] = q[17]
        floats[6 * c + j] = q[18]

