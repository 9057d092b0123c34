"""Screen-space refinement of virtual vertices on mesh reflectors (beyond the paper).

An explosion map finds a point's reflection cell to about a map texel, and the virtual
vertex it gives inherits that error (on four-spheres: 9 dB where the exact sphere method
reaches 20). The reflector's own item buffer knows, per pixel center s (screen space), the
reflector point Q(s) (world) and the reflected direction R(s) of the eye ray through it, with
the same interpolated normals the ray tracer uses. The reflection point of a scene point P is
the s where R(s) points at P: Gauss-Newton on c(s) = unit(P - Q(s)) - R(s), with Q and R
interpolated bilinearly between pixel centers, seeded by the explosion map's answer. The
virtual vertex then lies on the eye ray through Q(s), at the length of the path E -> Q -> P:
P' = E + unit(Q - E) (|Q - E| + |P - Q|).

The search stays inside one reflector part (its pixels in the reflector-only item buffer, so
that objects in front of the reflector do not cut it): mixed reflectors get one image per
part, as in the paper. A point whose search leaves the part, or does not converge, keeps its
explosion-map vertex.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

from ..parallel import claim
from ..raster.rasterize import recover_barycentrics


def reflector_grid(triangle: np.ndarray, b1: np.ndarray, b2: np.ndarray, corners: np.ndarray,
                   normals: np.ndarray, eye: np.ndarray,
                   out: tuple[np.ndarray | None, np.ndarray] | None = None):
    """Per pixel of a reflector-only item buffer: Q (H, W, 3) world point, R (H, W, 3) unit
    reflected direction of the eye ray (interpolated normal, two-sided); pixels the reflector
    does not cover hold NaN. `out`: (Q, R) (H, W, 3) float64 arrays to fill instead of new
    ones; Q None: R only (Q is returned as None)."""
    h, w = triangle.shape
    if out is None:
        q = np.full((h, w, 3), np.nan)
        r = np.full((h, w, 3), np.nan)
    else:
        q, r = out
        if q is not None:
            q.fill(np.nan)
        r.fill(np.nan)
    want_q = q is not None
    if not want_q:
        q = np.empty((0, 0, 3))
    _grid(triangle, b1, b2, corners, normals, np.asarray(eye, np.float64), q, r)
    return (q if want_q else None), r


@njit(cache=True, parallel=True)
def _grid(triangle, b1, b2, corners, normals, eye, q, r):
    h, w = triangle.shape
    want_q = q.shape[0] > 0  # (0, 0, 3): R only
    for y in prange(h):
        for x in range(w):
            t = triangle[y, x]
            if t < 0:
                continue
            _ray_at(t, b1[y, x], b2[y, x], corners, normals, eye, y, x, q, want_q, r)


@njit(cache=True, inline="always")
def _ray_at(t, c1, c2, corners, normals, eye, y, x, q, want_q, r):
    """R (and Q if want_q) at pixel (y, x) of triangle t at barycentrics c1, c2 (float32):
    the point, the interpolated normal (unit) and the eye ray reflected about it, worked in
    float64 component by component (the same values as whole-vector numpy arithmetic)."""
    c1, c2 = np.float64(c1), np.float64(c2)
    c0 = 1.0 - c1 - c2
    p0 = c0 * corners[t, 0, 0] + c1 * corners[t, 1, 0] + c2 * corners[t, 2, 0]
    p1 = c0 * corners[t, 0, 1] + c1 * corners[t, 1, 1] + c2 * corners[t, 2, 1]
    p2 = c0 * corners[t, 0, 2] + c1 * corners[t, 1, 2] + c2 * corners[t, 2, 2]
    n0 = c0 * normals[t, 0, 0] + c1 * normals[t, 1, 0] + c2 * normals[t, 2, 0]
    n1 = c0 * normals[t, 0, 1] + c1 * normals[t, 1, 1] + c2 * normals[t, 2, 1]
    n2 = c0 * normals[t, 0, 2] + c1 * normals[t, 1, 2] + c2 * normals[t, 2, 2]
    length = max(math.sqrt(n0 ** 2 + n1 ** 2 + n2 ** 2), 1e-30)
    n0, n1, n2 = n0 / length, n1 / length, n2 / length
    d0, d1, d2 = p0 - eye[0], p1 - eye[1], p2 - eye[2]
    length = math.sqrt(d0 ** 2 + d1 ** 2 + d2 ** 2)
    d0, d1, d2 = d0 / length, d1 / length, d2 / length
    dn = d0 * n0 + d1 * n1 + d2 * n2
    r[y, x, 0] = d0 - 2.0 * dn * n0
    r[y, x, 1] = d1 - 2.0 * dn * n1
    r[y, x, 2] = d2 - 2.0 * dn * n2
    if want_q:
        q[y, x, 0] = p0
        q[y, x, 1] = p1
        q[y, x, 2] = p2


@njit(cache=True, parallel=True, error_model="numpy")
def mirror_rays(triangle, mirror, drawn, clip_from_world, corners, normals, eye, y0, y1, x0,
                x1, r):
    """R of reflector_grid for the pixels of the box rows y0..y1-1, columns x0..x1-1 where
    `mirror` (H, W) is set and a triangle of `corners`, `normals` (T, 3, 3 world) is under
    it; the box's other pixels get NaN, the rest of r is left as it is. Each pixel's
    barycentrics are recovered from the clip-space corners of the triangle as drawn
    (`drawn`, float32 world; `clip_from_world`), as RasterBuffers.b1 and b2 would hold them
    (float32), so the primary pass need not make them for the whole image."""
    h, w = triangle.shape
    empty = np.empty((0, 0, 3))
    for y in prange(y0, y1):
        ny = 1.0 - (y + 0.5) * (2.0 / h)
        for x in range(x0, x1):
            t = triangle[y, x]
            if t < 0 or not mirror[y, x]:
                r[y, x, 0] = np.nan
                r[y, x, 1] = np.nan
                r[y, x, 2] = np.nan
                continue
            c1, c2 = recover_barycentrics(drawn, t, clip_from_world,
                                          (x + 0.5) * (2.0 / w) - 1.0, ny)
            _ray_at(t, np.float32(c1), np.float32(c2), corners, normals, eye, y, x, empty,
                    False, r)


NONE, EXACT, BOUNDARY = 0, 1, 2


def refine_virtual(points: np.ndarray, seeds: np.ndarray, inside: np.ndarray, q: np.ndarray,
                   r: np.ndarray, eye: np.ndarray, retry_seeds: np.ndarray | None = None,
                   iterations: int = 20, reach: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Virtual vertices of `points` (N, 3) by the search above, from screen positions `seeds`
    (N, 2, pixels; NaN: no seed) within the pixels where `inside` (H, W) holds. A point whose
    seed does not lead to its reflection (outside the part, or a walk blocked by a hole in
    it) tries again from `retry_seeds` (N, 2; see tiles.PartTiles.scan).
    `reach` (N,) bool, if given: the tiles' verdict (PartTiles.scan) that some ray of the
    part may pass the point. A point no ray reaches has no reflection in the part (an EXACT
    end lies within 0.6 degrees of a ray of the part, inside the tiles' 1 degree margin), so
    a retry could only end at the boundary too, which would not replace a first walk's
    boundary answer: it is skipped, with the same result.
    Returns (virtual points (N, 3), status (N,) int8): EXACT where the reflection was found,
    BOUNDARY where the search left the part (see _walk), NONE (rows NaN) where it never
    sampled the part."""
    out = np.full(points.shape, np.nan)
    ok = np.zeros(points.shape[0], np.int8)
    if retry_seeds is None:
        retry_seeds = np.full(points.shape[:1] + (2,), np.nan)
    if reach is None:
        reach = np.ones(points.shape[0], np.bool_)
    _refine(np.ascontiguousarray(points, np.float64), np.ascontiguousarray(seeds, np.float64),
            inside, q, r, np.asarray(eye, np.float64), iterations,
            np.ascontiguousarray(retry_seeds, np.float64), np.ascontiguousarray(reach, np.bool_),
            out, ok, numba.get_num_threads())
    return out, ok


@njit(cache=True, inline="always")
def _sample(inside, q, r, sx, sy):
    """Bilinear Q and R at screen point (sx, sy) from the four nearest pixel centers that lie
    inside the part (missing ones take the weight of the others): (ok, Q x, y, z, R x, y, z)
    with R unit; ok False (and the rest meaningless) if none does. Scalars, not arrays: the
    walk keeps them in registers."""
    h, w = inside.shape
    fx = sx - 0.5
    fy = sy - 0.5
    x0 = int(math.floor(fx))
    y0 = int(math.floor(fy))
    ax = fx - x0
    ay = fy - y0
    total = 0.0
    q0 = q1 = q2 = r0 = r1 = r2 = 0.0
    for dy in range(2):
        for dx in range(2):
            x = x0 + dx
            y = y0 + dy
            if x < 0 or y < 0 or x >= w or y >= h or not inside[y, x]:
                continue
            wt = (ax if dx else 1.0 - ax) * (ay if dy else 1.0 - ay)
            if wt <= 0.0:
                continue
            total += wt
            q0 += wt * q[y, x, 0]
            q1 += wt * q[y, x, 1]
            q2 += wt * q[y, x, 2]
            r0 += wt * r[y, x, 0]
            r1 += wt * r[y, x, 1]
            r2 += wt * r[y, x, 2]
    if total <= 1e-9:
        return False, q0, q1, q2, r0, r1, r2
    norm = math.sqrt(r0 ** 2 + r1 ** 2 + r2 ** 2)
    return True, q0 / total, q1 / total, q2 / total, r0 / norm, r1 / norm, r2 / norm


@njit(cache=True, inline="always")
def _residual(p, inside, q, r, sx, sy):
    """(ok, c x, y, z, Q x, y, z, R x, y, z): c = unit(p - Q) - R at screen point (sx, sy),
    with the sample's Q and R; ok False where the part is not sampled there or p is Q."""
    ok, q0, q1, q2, r0, r1, r2 = _sample(inside, q, r, sx, sy)
    if not ok:
        return False, 0.0, 0.0, 0.0, q0, q1, q2, r0, r1, r2
    d0 = p[0] - q0
    d1 = p[1] - q1
    d2 = p[2] - q2
    length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if length <= 0.0:
        return False, 0.0, 0.0, 0.0, q0, q1, q2, r0, r1, r2
    return True, d0 / length - r0, d1 / length - r1, d2 / length - r2, q0, q1, q2, r0, r1, r2


@njit(cache=True)
def _walk(p, inside, q, r, sx, sy, iterations):
    """Gauss-Newton from screen point (sx, sy) toward the reflection point of p: (status,
    Q x, y, z). EXACT with Q there; BOUNDARY where the walk leaves the part (the reflection
    lies past a silhouette, or on another part): then the last step is taken on the linear
    model from the last point inside, Q extrapolated along its screen derivatives, so that
    polygons reaching out there stretch past the part's edge (and are masked) as exact ones
    would; NONE if the part was never sampled (Q meaningless)."""
    h, w = inside.shape
    step_h = 0.5  # finite-difference step, pixels
    status = NONE
    e0 = e1 = e2 = 0.0  # Q at the end (extrapolated, unless exact)
    r0 = r1 = r2 = 0.0  # R at the last point inside
    c0 = c1 = c2 = 0.0
    for _ in range(iterations):
        if not (0.0 <= sx < w and 0.0 <= sy < h):
            break
        ok, c0, c1, c2, q0, q1, q2, r0, r1, r2 = _residual(p, inside, q, r, sx, sy)
        if not ok:
            break
        status = BOUNDARY
        e0, e1, e2 = q0, q1, q2
        sign_x = 1.0
        ok, cx0, cx1, cx2, qx0, qx1, qx2, _, _, _ = _residual(p, inside, q, r, sx + step_h, sy)
        if not ok:
            ok, cx0, cx1, cx2, qx0, qx1, qx2, _, _, _ = _residual(p, inside, q, r,
                                                                  sx - step_h, sy)
            if not ok:
                break
            sign_x = -1.0
        sign_y = 1.0
        ok, cy0, cy1, cy2, qy0, qy1, qy2, _, _, _ = _residual(p, inside, q, r, sx, sy + step_h)
        if not ok:
            ok, cy0, cy1, cy2, qy0, qy1, qy2, _, _, _ = _residual(p, inside, q, r, sx,
                                                                  sy - step_h)
            if not ok:
                break
            sign_y = -1.0
        # Jacobian columns (per pixel) and the 2x2 normal equations
        jx0 = sign_x * (cx0 - c0) / step_h
        jx1 = sign_x * (cx1 - c1) / step_h
        jx2 = sign_x * (cx2 - c2) / step_h
        jy0 = sign_y * (cy0 - c0) / step_h
        jy1 = sign_y * (cy1 - c1) / step_h
        jy2 = sign_y * (cy2 - c2) / step_h
        a00 = ((0.0 + jx0 * jx0) + jx1 * jx1) + jx2 * jx2
        a01 = ((0.0 + jx0 * jy0) + jx1 * jy1) + jx2 * jy2
        a11 = ((0.0 + jy0 * jy0) + jy1 * jy1) + jy2 * jy2
        g0 = ((0.0 + jx0 * c0) + jx1 * c1) + jx2 * c2
        g1 = ((0.0 + jy0 * c0) + jy1 * c1) + jy2 * c2
        det = a00 * a11 - a01 * a01
        if not det > 1e-30:
            break
        dx = -(a11 * g0 - a01 * g1) / det
        dy = -(a00 * g1 - a01 * g0) / det
        length = math.sqrt(dx * dx + dy * dy)
        if length > 8.0:  # a trust region: no jumps across the part
            dx *= 8.0 / length
            dy *= 8.0 / length
        e0 = q0 + (sign_x * (qx0 - q0) * dx + sign_y * (qy0 - q0) * dy) / step_h
        e1 = q1 + (sign_x * (qx1 - q1) * dx + sign_y * (qy1 - q1) * dy) / step_h
        e2 = q2 + (sign_x * (qx2 - q2) * dx + sign_y * (qy2 - q2) * dy) / step_h
        if length < 1e-3:
            if c0 ** 2 + c1 ** 2 + c2 ** 2 <= 1e-4:  # else a local minimum
                status = EXACT
                e0, e1, e2 = q0, q1, q2
            break
        sx += dx
        sy += dy
    if status == EXACT:
        d0 = p[0] - e0
        d1 = p[1] - e1
        d2 = p[2] - e2
        if d0 * r0 + d1 * r1 + d2 * r2 <= 0.0:
            status = BOUNDARY  # on the line of the ray, but behind its start
    return status, e0, e1, e2


_CHUNK = 64  # points claimed at a time by a thread in _refine


@njit(cache=True, parallel=True)
def _refine(points, seeds, inside, q, r, eye, iterations, retry, reach, out, ok, threads):
    """refine_virtual's search, point by point. Walks take 1 to 2 x `iterations` steps, so
    points go in chunks claimed by whichever thread is free (parallel.py); each point's
    answer is its own, whoever finds it."""
    n = points.shape[0]
    chunks = (n + _CHUNK - 1) // _CHUNK
    claimed = np.zeros(1, np.int64)
    for _worker in prange(min(threads, chunks)):
        while True:
            c = claim(claimed)
            if c >= chunks:
                break
            for k in range(c * _CHUNK, min(n, (c + 1) * _CHUNK)):
                _refine_point(k, points, seeds, inside, q, r, eye, iterations, retry, reach,
                              out, ok)


@njit(cache=True, inline="always")
def _refine_point(k, points, seeds, inside, q, r, eye, iterations, retry, reach, out, ok):
    """Point k of _refine into out[k] and ok[k]."""
    p = points[k]
    status = NONE
    e0 = e1 = e2 = 0.0
    if np.isfinite(seeds[k, 0]) and np.isfinite(seeds[k, 1]):
        status, e0, e1, e2 = _walk(p, inside, q, r, seeds[k, 0], seeds[k, 1], iterations)
    if (status == NONE or (status == BOUNDARY and reach[k])) and np.isfinite(retry[k, 0]):
        again, f0, f1, f2 = _walk(p, inside, q, r, retry[k, 0], retry[k, 1], iterations)
        if again == EXACT or (status == NONE and again != NONE):
            status = again
            e0, e1, e2 = f0, f1, f2
    if status == NONE:
        return
    d0, d1, d2 = p[0] - e0, p[1] - e1, p[2] - e2
    v0, v1, v2 = e0 - eye[0], e1 - eye[1], e2 - eye[2]
    le = math.sqrt(v0 ** 2 + v1 ** 2 + v2 ** 2)
    lp = math.sqrt(d0 ** 2 + d1 ** 2 + d2 ** 2)
    out[k, 0] = eye[0] + v0 / le * (le + lp)
    out[k, 1] = eye[1] + v1 / le * (le + lp)
    out[k, 2] = eye[2] + v2 / le * (le + lp)
    ok[k] = status
