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
    _CULL_SHIFT,
    _CULLED,
    _SIMPLE,
    CULL_BACK,
    CULL_FRONT,
    FLAG_MIRROR,
    FLAG_SKIP,
)


@njit(cache=True, inline="always")
def _mul(a, b):
    """a * b (int64) of two int64 that fit int32, as every factor of a setup does (snapped
    coordinates and their differences from a center of the guard band are below 2^30 in
    magnitude, see fixed.py): vectorised, one signed 32 x 32 -> 64 bit multiply (AVX2 has
    none of 64 x 64 bits: the compiler made it of three and shifts)."""
    return np.int64(np.int32(a)) * np.int64(np.int32(b))


@njit(cache=True, inline="always")
def _real(a):
    """float(a) of an int64 that fits int32, as _mul's factors (AVX2 converts int32 to
    float64, not int64: the compiler converted one lane at a time)."""
    return np.float64(np.int32(a))


@njit(cache=True, inline="always")
def _facing(x0, y0, x1, y1, x2, y2, cull):
    """(twice the signed area, whether `cull` keeps it) of a snapped screen triangle."""
    area = _mul(x1 - x0, y2 - y0) - _mul(x2 - x0, y1 - y0)
    # screen y points down: a counter-clockwise (front) triangle has negative area here
    return area, ((area != 0) & (((cull & CULL_BACK) == 0) | (area < 0))
                  & (((cull & CULL_FRONT) == 0) | (area > 0)))


@njit(cache=True, inline="always")
def triangle_cull(flag, cull):
    """The culling of a triangle with rasterizer flags `flag` in a pass culling by `cull`:
    the pass's, and its back face too where FLAG_CULL_BACK is set, its front face where
    FLAG_CULL_FRONT is (the modes are bits: CULL_BACK | CULL_FRONT drops both faces)."""
    return cull | ((flag >> _CULL_SHIFT) & (CULL_BACK | CULL_FRONT))


@njit(cache=True, inline="always")
def _centers(x0, y0, x1, y1, x2, y2, bits):
    """(first_x, last_x, first_y, last_y): the pixel centers inside a snapped screen
    triangle's corners' box."""
    half = np.int64(1) << (bits - 1)
    return (-((half - min(x0, x1, x2)) >> bits), (max(x0, x1, x2) - half) >> bits,
            -((half - min(y0, y1, y2)) >> bits), (max(y0, y1, y2) - half) >> bits)


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
    area, facing = _facing(x0, y0, x1, y1, x2, y2, cull)
    # wind every triangle one way: inside is then where all edges are >= 0
    flip = area < 0
    x1, x2 = (x2, x1) if flip else (x1, x2)
    y1, y2 = (y2, y1) if flip else (y1, y2)
    w1, w2 = (w2, w1) if flip else (w1, w2)
    area = -area if flip else area
    one = np.int64(1)
    half = one << (bits - 1)
    first_x, last_x, first_y, last_y = _centers(x0, y0, x1, y1, x2, y2, bits)
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
    e0 = _mul(a0, px0 - x1) + _mul(b0, py0 - y1) + bias0
    e1 = _mul(a1, px0 - x2) + _mul(b1, py0 - y2) + bias1
    e2 = _mul(a2, px0 - x0) + _mul(b2, py0 - y0) + bias2
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
    dzdx = (_real(a0) * w0 + _real(a1) * w1 + _real(a2) * w2) * sx * inv_area
    dzdy = (_real(b0) * w0 + _real(b1) * w1 + _real(b2) * w2) * sx * inv_area
    cx = (first_x << bits) + half
    cy = (first_y << bits) + half
    z_ref = ((_mul(a0, cx - x1) + _mul(b0, cy - y1)) * w0
             + (_mul(a1, cx - x2) + _mul(b1, cy - y2)) * w1
             + (_mul(a2, cx - x0) + _mul(b2, cy - y0)) * w2) * inv_area
    return (drawn, xs, xe - xs + 1, ys, ye, first_y, e0, e1, e2, sa0, sa1, sa2, sb0, sb1,
            sb2, z_ref, dzdx, dzdy, dzdx * _real(xs - first_x))



@njit(cache=True, error_model="numpy")
def _run_setup(corners, flags, m, planes, n_cut, width, height, bits, scale, cull, top,
               bottom, col0, col1, t0, count, ints, floats, status):
    """Setup of triangles t0 .. t0 + count - 1 (j = t - t0), in loops over the run without
    branches (vectorised): their corners' clip coordinates, status[j] _CULLED (outside one
    side of the frustum or one of the first n_cut planes, or FLAG_SKIP), _CLIPPED (a plane
    cuts it, or it leaves the guard band) or _SIMPLE, and for a simple one its corners'
    snapped screen x, y (`ints` rows 2k, 2k + 1) and 1/w (`floats` row k), the very
    values (same operations, same order) as a scalar loop per triangle would give.
    Returns `kept`, how many may be drawn (simple, kept by its culling (`triangle_cull`:
    the listed ones' setups may then take the pass's `cull`), a pixel center of the
    box inside their corners' box: a cheap test), listed in order: the i-th (i < kept) is
    triangle t0 + ints[21 * _CHUNK + i], its `_setup` in column i (ints rows 20: drawn, 6
    .. 19: xs .. sb2; floats rows 3 .. 6: z_ref .. zx0). Only those are set up: at 1M
    triangles (room + icospheres, back faces culled) a third, of which 60% are drawn;
    the setup of all took 20 of the 39 ms, that of a third 4 ms. A run where more than
    half pass the test is set up whole instead, in place (kept = count, row 21 j itself):
    listing and gathering cost more than setting up the rest.
    `ints`, `floats`: (22 * _CHUNK) and (8 * _CHUNK)."""
    # the run's flags through a view indexed from 0 (flags[t0 + j] pays numba's
    # negative-index wraparound in every vectorised loop that reads it: 10% of the setup)
    run_flags = flags[t0:t0 + count]
    # the corners read in place (copied to rows of their own first, 9 values a triangle,
    # took 3.6 ms of the setup at 1M triangles; read where they are, the loops take 1 more)
    run = corners[t0:t0 + count]
    m00, m01, m02, m03 = m[0, 0], m[0, 1], m[0, 2], m[0, 3]
    m10, m11, m12, m13 = m[1, 0], m[1, 1], m[1, 2], m[1, 3]
    m20, m21, m22, m23 = m[2, 0], m[2, 1], m[2, 2], m[2, 3]
    m30, m31, m32, m33 = m[3, 0], m[3, 1], m[3, 2], m[3, 3]
    # planes past the first two (rare): status[j] bit 0 when all corners are outside one of
    # them, bit 1 when some corner is outside one, read by the loop below (else 0)
    for j in range(count):
        status[j] = 0
    for p in range(2, n_cut):
        a, b, c, d = planes[p, 0], planes[p, 1], planes[p, 2], planes[p, 3]
        for j in range(count):
            o = np.uint8(0)
            s = np.uint8(1)
            for k in range(3):
                x = np.float64(run[j, k, 0])
                y = np.float64(run[j, k, 1])
                z = np.float64(run[j, k, 2])
                cx = m00 * x + m01 * y + m02 * z + m03
                cy = m10 * x + m11 * y + m12 * z + m13
                cz = m20 * x + m21 * y + m22 * z + m23
                cw = m30 * x + m31 * y + m32 * z + m33
                outside = a * cx + b * cy + c * cz + d * cw < 0.0
                o |= np.uint8(2) if outside else np.uint8(0)
                s &= np.uint8(1) if outside else np.uint8(0)
            status[j] |= o | s
    # status: _CULLED when outside one side of the frustum, or all corners outside one of
    # the planes; else _CLIPPED when a plane or the guard band cuts it (screen coordinates
    # beyond the band could overflow the fixed-point range); else _SIMPLE. The first two
    # planes are tested here (a plane missing: zeros, never outside), any others above (the
    # order of the planes never matters). Then a simple triangle's corners snapped (the
    # others' 0: only a simple one's are used, and safe to snap), and whether it may be
    # drawn (kept by `cull`, some pixel center of the box inside its corners' box) in row
    # 20: one loop per triangle, its clip coordinates never written out
    gx = planes[n_cut, 3]
    gy = planes[n_cut + 2, 3]
    pa, pb, pc, pd = (planes[0, 0], planes[0, 1], planes[0, 2], planes[0, 3]) if n_cut > 0 \
        else (0.0, 0.0, 0.0, 0.0)
    qa, qb, qc, qd = (planes[1, 0], planes[1, 1], planes[1, 2], planes[1, 3]) if n_cut > 1 \
        else (0.0, 0.0, 0.0, 0.0)
    c = _CHUNK
    fhalf = float(np.int64(1) << (bits - 1))
    unit = 1.0 / scale
    fcol0, fcol1, ftop, fbottom = float(col0), float(col1 - 1), float(top), float(bottom - 1)
    for j in range(count):
        x = np.float64(run[j, 0, 0])
        y = np.float64(run[j, 0, 1])
        z = np.float64(run[j, 0, 2])
        x0 = m00 * x + m01 * y + m02 * z + m03
        y0 = m10 * x + m11 * y + m12 * z + m13
        z0 = m20 * x + m21 * y + m22 * z + m23
        w0 = m30 * x + m31 * y + m32 * z + m33
        x = np.float64(run[j, 1, 0])
        y = np.float64(run[j, 1, 1])
        z = np.float64(run[j, 1, 2])
        x1 = m00 * x + m01 * y + m02 * z + m03
        y1 = m10 * x + m11 * y + m12 * z + m13
        z1 = m20 * x + m21 * y + m22 * z + m23
        w1 = m30 * x + m31 * y + m32 * z + m33
        x = np.float64(run[j, 2, 0])
        y = np.float64(run[j, 2, 1])
        z = np.float64(run[j, 2, 2])
        x2 = m00 * x + m01 * y + m02 * z + m03
        y2 = m10 * x + m11 * y + m12 * z + m13
        z2 = m20 * x + m21 * y + m22 * z + m23
        w2 = m30 * x + m31 * y + m32 * z + m33
        p0 = pa * x0 + pb * y0 + pc * z0 + pd * w0 < 0.0
        p1 = pa * x1 + pb * y1 + pc * z1 + pd * w1 < 0.0
        p2 = pa * x2 + pb * y2 + pc * z2 + pd * w2 < 0.0
        q0 = qa * x0 + qb * y0 + qc * z0 + qd * w0 < 0.0
        q1 = qa * x1 + qb * y1 + qc * z1 + qd * w1 < 0.0
        q2 = qa * x2 + qb * y2 + qc * z2 + qd * w2 < 0.0
        extra = status[j]
        out = (((x0 < -w0) & (x1 < -w1) & (x2 < -w2)) | ((x0 > w0) & (x1 > w1) & (x2 > w2))
               | ((y0 < -w0) & (y1 < -w1) & (y2 < -w2)) | ((y0 > w0) & (y1 > w1) & (y2 > w2))
               | ((run_flags[j] & FLAG_SKIP) != 0) | (p0 & p1 & p2) | (q0 & q1 & q2)
               | ((extra & 1) != 0))
        cut = ((abs(x0) > gx * w0) | (abs(x1) > gx * w1) | (abs(x2) > gx * w2)
               | (abs(y0) > gy * w0) | (abs(y1) > gy * w1) | (abs(y2) > gy * w2)
               | p0 | p1 | p2 | q0 | q1 | q2 | ((extra & 2) != 0))
        status[j] = _CULLED if out else (_CLIPPED if cut else _SIMPLE)
        simple = not (out | cut)
        iw0 = 1.0 / (w0 if simple else 1.0)
        iw1 = 1.0 / (w1 if simple else 1.0)
        iw2 = 1.0 / (w2 if simple else 1.0)
        sx0, sy0 = screen_from_ndc(x0 * iw0, y0 * iw0, width, height)
        sx1, sy1 = screen_from_ndc(x1 * iw1, y1 * iw1, width, height)
        sx2, sy2 = screen_from_ndc(x2 * iw2, y2 * iw2, width, height)
        # snapped as `_snap` does, its floor kept (for the test below) before the int32
        f0 = np.floor((sx0 if simple else 0.0) * scale + 0.5)
        g0 = np.floor((sy0 if simple else 0.0) * scale + 0.5)
        f1 = np.floor((sx1 if simple else 0.0) * scale + 0.5)
        g1 = np.floor((sy1 if simple else 0.0) * scale + 0.5)
        f2 = np.floor((sx2 if simple else 0.0) * scale + 0.5)
        g2 = np.floor((sy2 if simple else 0.0) * scale + 0.5)
        u0, v0 = np.int64(np.int32(f0)), np.int64(np.int32(g0))
        u1, v1 = np.int64(np.int32(f1)), np.int64(np.int32(g1))
        u2, v2 = np.int64(np.int32(f2)), np.int64(np.int32(g2))
        ints[j], ints[c + j], ints[2 * c + j], ints[3 * c + j] = u0, v0, u1, v1
        ints[4 * c + j], ints[5 * c + j] = u2, v2
        floats[j], floats[c + j], floats[2 * c + j] = iw0, iw1, iw2
        facing = _facing(u0, v0, u1, v1, u2, v2, triangle_cull(run_flags[j], cull))[1]
        # the centers test in float64, exact (integers below 2^31, a power of 2 scale)
        first_x = np.ceil((min(f0, f1, f2) - fhalf) * unit)
        last_x = np.floor((max(f0, f1, f2) - fhalf) * unit)
        first_y = np.ceil((min(g0, g1, g2) - fhalf) * unit)
        last_y = np.floor((max(g0, g1, g2) - fhalf) * unit)
        ints[20 * c + j] = (facing & simple & (max(first_x, fcol0) <= min(last_x, fcol1))
                            & (max(first_y, ftop) <= min(last_y, fbottom)))
    kept = 0
    for j in range(count):
        kept += ints[20 * c + j]
    if 2 * kept > count:
        # most may be drawn: the setups of all, in place (column j, reading rows 0 .. 5 and
        # floats 0 .. 2), cheaper than listing and gathering those (a simple triangle not
        # kept by the test is not drawn by its setup either; the others have corners 0:
        # degenerate, not drawn); each its own index in row 21
        for j in range(count):
            q = _setup(ints[j], ints[c + j], floats[j], ints[2 * c + j], ints[3 * c + j],
                       floats[c + j], ints[4 * c + j], ints[5 * c + j], floats[2 * c + j],
                       1.0 / MIRROR_TIE if run_flags[j] & FLAG_MIRROR else 1.0,
                       triangle_cull(run_flags[j], cull), bits, top, bottom, col0, col1)
            _store_setup(ints, floats, c, j, q)
            ints[21 * c + j] = j
        return count
    # else those that may be drawn listed (their j in row 21) without a branch per
    # triangle, then their corners gathered into rows 6 .. 11 (ints) and 3 .. 5 (floats),
    # and their key scale into row 7 (floats): the setup's loop reads them in order (in
    # place, each read before the setup of the same triangle overwrites it)
    kept = 0
    for j in range(count):
        ints[21 * c + kept] = j
        kept += ints[20 * c + j]
    for i in range(kept):
        j = ints[21 * c + i]
        for r in range(6):
            ints[(6 + r) * c + i] = ints[r * c + j]
        for r in range(3):
            floats[(3 + r) * c + i] = floats[r * c + j]
        floats[7 * c + i] = 1.0 / MIRROR_TIE if run_flags[j] & FLAG_MIRROR else 1.0
    # the setups of those (see _setup), their keep flag in row 20: drawn (one array for the
    # ints, one for the floats, rows a constant _CHUNK apart: the compiler sees they never
    # overlap)
    for i in range(kept):
        q = _setup(ints[6 * c + i], ints[7 * c + i], floats[3 * c + i], ints[8 * c + i],
                   ints[9 * c + i], floats[4 * c + i], ints[10 * c + i], ints[11 * c + i],
                   floats[5 * c + i], floats[7 * c + i], cull, bits, top, bottom, col0, col1)
        _store_setup(ints, floats, c, i, q)
    return kept


@njit(cache=True, inline="always")
def _store_setup(ints, floats, c, i, q):
    """A `_setup` (q) into column i of a run's setup rows (ints 20: drawn, 6 .. 19: xs ..
    sb2; floats 3 .. 6: z_ref .. zx0), rows c apart."""
    ints[20 * c + i] = q[0]
    ints[6 * c + i] = q[1]
    ints[7 * c + i] = q[2]
    ints[8 * c + i] = q[3]
    ints[9 * c + i] = q[4]
    ints[10 * c + i] = q[5]
    ints[11 * c + i] = q[6]
    ints[12 * c + i] = q[7]
    ints[13 * c + i] = q[8]
    ints[14 * c + i] = q[9]
    ints[15 * c + i] = q[10]
    ints[16 * c + i] = q[11]
    ints[17 * c + i] = q[12]
    ints[18 * c + i] = q[13]
    ints[19 * c + i] = q[14]
    floats[3 * c + i] = q[15]
    floats[4 * c + i] = q[16]
    floats[5 * c + i] = q[17]
    floats[6 * c + i] = q[18]
