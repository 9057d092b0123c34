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

from ..parallel import claim, counter
from ..raster.rasterize import (
    RasterBuffers,
    barycentrics_at,
    clip_corners,
    recover_barycentrics,
)
from .tiles import owner_plane


def reflector_grid(triangle: np.ndarray, b1: np.ndarray, b2: np.ndarray, corners: np.ndarray,
                   normals: np.ndarray, eye: np.ndarray,
                   out: tuple[np.ndarray | None, np.ndarray] | None = None):
    """Per pixel of a reflector-only item buffer, from its barycentrics b1, b2: Q (H, W, 3)
    world point, R (H, W, 3) unit reflected direction of the eye ray (interpolated normal,
    two-sided); pixels the reflector does not cover hold NaN. Every pixel of the frame:
    the tests' grids, and the bytes reflector_rays (a view's rays, over the reflector's
    pixels only) and mirror_rays are held to. `out`: (Q, R) (H, W, 3) float64 arrays to
    fill instead of new ones; Q None: R only (Q is returned as None)."""
    h, w = triangle.shape
    if out is None:
        # not filled with NaN first: _grid writes every pixel (one pass over 2 x 6 MB at
        # 512^2, not two)
        q = np.empty((h, w, 3))
        r = np.empty((h, w, 3))
    else:
        q, r = out
    want_q = q is not None
    if not want_q:
        q = np.empty((0, 0, 3))
    _grid(triangle, b1, b2, corners, normals, np.asarray(eye, np.float64), q, r)
    return (q if want_q else None), r


@njit(cache=True, parallel=True)
def _grid(triangle, b1, b2, corners, normals, eye, q, r):
    """reflector_grid into q (unless (0, 0, 3)) and r: every pixel written, NaN where no
    triangle is."""
    h, w = triangle.shape
    want_q = q.shape[0] > 0  # (0, 0, 3): R only
    for y in prange(h):
        for x in range(w):
            t = triangle[y, x]
            if t < 0:
                for i in range(3):
                    r[y, x, i] = np.nan
                    if want_q:
                        q[y, x, i] = np.nan
                continue
            _ray_at(t, b1[y, x], b2[y, x], corners, normals, eye, y, x, q, want_q, r)


def reflector_rays(alone: RasterBuffers, corners: np.ndarray, normals: np.ndarray,
                   eye: np.ndarray, spans: np.ndarray,
                   out: tuple[np.ndarray, np.ndarray] | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """reflector_grid's Q and R (H, W, 3) for the pixels of each row's span only (spans
    (H, 2): columns spans[y, 0] .. spans[y, 1] - 1 of row y; part_views makes them, the
    columns of the reflector's pixels), their barycentrics recovered from `alone`'s drawn
    corners in the kernel (the bytes RasterBuffers.b1 and b2 would hold). The other pixels
    are left unwritten: every reader looks at a pixel only where a part owns it (the
    mask covers a quarter of its frame, and a whole-frame pass made the barycentrics of
    every pixel and wrote 12 MB of fresh pages). `out`: (Q, R) to fill instead of new
    arrays."""
    assert alone.corners is not None, "reflector_rays recovers barycentrics: drawn corners"
    h, w = alone.triangle.shape
    q, r = out if out is not None else (np.empty((h, w, 3)), np.empty((h, w, 3)))
    _grid_spans(alone.triangle, alone.corners, alone.clip_from_world, corners, normals,
                np.asarray(eye, np.float64), spans, q, r, numba.get_num_threads())
    return q, r


@njit(cache=True, parallel=True, error_model="numpy")
def _grid_spans(triangle, drawn, clip_from_world, corners, normals, eye, spans, q, r,
                threads):
    """reflector_rays into q and r: _grid over each row's span, with each pixel's b1, b2
    recovered as _barycentrics makes them (float32; a triangle's clip corners made once
    for each run of its pixels along a row). Rows in chunks claimed by whichever thread
    is free (parallel.py: a reflector's rows lie in a band of the image, which a fixed
    share per thread splits unevenly); each pixel's values are its own."""
    h = triangle.shape[0]
    chunks = (h + _GRID_ROWS - 1) // _GRID_ROWS
    claimed = counter()
    for _worker in prange(min(threads, chunks)):
        while True:
            c = claim(claimed)
            if c >= chunks:
                break
            for y in range(c * _GRID_ROWS, min(h, (c + 1) * _GRID_ROWS)):
                _grid_row(triangle, drawn, clip_from_world, corners, normals, eye, spans, q,
                          r, y)


_GRID_ROWS = 8  # rows a _grid_spans chunk


@njit(cache=True, inline="always", error_model="numpy")
def _grid_row(triangle, drawn, clip_from_world, corners, normals, eye, spans, q, r, y):
    """Row y of _grid_spans."""
    h, w = triangle.shape
    ny = 1.0 - (y + 0.5) * (2.0 / h)
    last = -1  # the triangle whose clip corners `clip` holds (a row crosses each in a run)
    clip = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    for x in range(spans[y, 0], spans[y, 1]):
        t = triangle[y, x]
        if t < 0:
            for i in range(3):
                r[y, x, i] = np.nan
                q[y, x, i] = np.nan
            continue
        if t != last:
            clip = clip_corners(drawn, t, clip_from_world)
            last = t
        c1, c2 = barycentrics_at(clip, (x + 0.5) * (2.0 / w) - 1.0, ny)
        _ray_at(t, np.float32(c1), np.float32(c2), corners, normals, eye, y, x, q, True, r)


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
                   iterations: int = 20, reach: np.ndarray | None = None,
                   part: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Virtual vertices of `points` (N, 3) by the search above, from screen positions `seeds`
    (N, 2, pixels; NaN: no seed) within the part's pixels: where `inside` (H, W, bool)
    holds, or with `part`, where the owner plane `inside` (view.part_views) is `part`. A
    point whose seed does not lead to its reflection (outside the part, or a walk blocked by
    a hole in it) tries again from `retry_seeds` (N, 2; see tiles.PartTiles.scan).
    `reach` (N,) bool, if given: the tiles' verdict (PartTiles.scan) that some ray of the
    part may pass the point. A point no ray reaches has no reflection in the part (an EXACT
    end lies within 0.6 degrees of a ray of the part, inside the tiles' 1 degree margin), so
    a retry could only end at the boundary too, which would not replace a first walk's
    boundary answer: it is skipped, with the same result.
    Returns (virtual points (N, 3), status (N,) int8): EXACT where the reflection was found,
    BOUNDARY where the search left the part (see _walk), NONE (rows NaN) where it never
    sampled the part."""
    owner, part = owner_plane(inside, part)
    return refine_parts(points, seeds, owner, np.full(points.shape[0], part, np.int32), q, r,
                        eye, retry_seeds, iterations, reach)


def refine_parts(points: np.ndarray, seeds: np.ndarray, owner: np.ndarray, parts: np.ndarray,
                 q: np.ndarray, r: np.ndarray, eye: np.ndarray,
                 retry_seeds: np.ndarray | None = None, iterations: int = 20,
                 reach: np.ndarray | None = None,
                 out: tuple[np.ndarray, np.ndarray] | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """refine_virtual for points of several parts of one reflector at once: point i
    searched within part parts[i] (N,) int32 of the owner plane `owner` (view.part_views).
    Each point's answer is the one refine_virtual gives it alone; one parallel region for
    all parts (parts.py: the mask's 14 parts made 14 regions, the small ones' walks left
    a thread idle at their ends). `out`: (N, 3) float64 and (N,) int8 arrays to answer
    in (reused across frames), else fresh ones."""
    if out is None:
        out = np.empty(points.shape), np.empty(points.shape[0], np.int8)
    out, ok = out
    out.fill(np.nan)
    ok.fill(0)
    if retry_seeds is None:
        retry_seeds = np.full(points.shape[:1] + (2,), np.nan)
    if reach is None:
        reach = np.ones(points.shape[0], np.bool_)
    _refine(np.ascontiguousarray(points, np.float64), np.ascontiguousarray(seeds, np.float64),
            owner, np.ascontiguousarray(parts, np.int32), q, r, np.asarray(eye, np.float64),
            iterations, np.ascontiguousarray(retry_seeds, np.float64),
            np.ascontiguousarray(reach, np.bool_), out, ok, numba.get_num_threads())
    return out, ok


@njit(cache=True, inline="always")
def _sample_slope(owner, part, q, r, sx, sy):
    """Q and R at screen point (sx, sy), blended bilinearly from the four nearest pixel
    centers of the part (owner == part; missing ones take the weight of the others, R made
    unit), with their derivatives along screen x and
    y (per pixel), those of the bilinear blend of the cell's corners inside the part (the
    weights renormalized: Q = S / T, dQ = (dS - Q dT) / T; R = B / |B|, dR = (dB - R (R.dB))
    / |B|): (corners, Q, dQ/dx, dQ/dy, R, dR/dx, dR/dy), each as three scalars; corners:
    how many of the cell's corners are the part's (1: Q and R are constant, their
    derivatives zero up to rounding), 0 (and the rest meaningless) if none carries weight.
    Corners of zero weight count in the derivatives (a one-sided derivative on a cell's
    edge). Scalars, not arrays:
    the walk keeps them in registers."""
    h, w = owner.shape
    fx = sx - 0.5
    fy = sy - 0.5
    x0 = int(math.floor(fx))
    y0 = int(math.floor(fy))
    ax = fx - x0
    ay = fy - y0
    total = tx = ty = 0.0
    corners = 0
    q0 = q1 = q2 = r0 = r1 = r2 = 0.0
    qx0 = qx1 = qx2 = rx0 = rx1 = rx2 = 0.0
    qy0 = qy1 = qy2 = ry0 = ry1 = ry2 = 0.0
    for dy in range(2):
        for dx in range(2):
            x = x0 + dx
            y = y0 + dy
            if x < 0 or y < 0 or x >= w or y >= h or owner[y, x] != part:
                continue
            wx = ax if dx else 1.0 - ax
            wy = ay if dy else 1.0 - ay
            wt = wx * wy
            gx = wy if dx else -wy  # d wt / d sx
            gy = wx if dy else -wx
            a0, a1, a2 = q[y, x, 0], q[y, x, 1], q[y, x, 2]
            b0, b1, b2 = r[y, x, 0], r[y, x, 1], r[y, x, 2]
            corners += 1
            total += wt
            tx += gx
            ty += gy
            q0 += wt * a0
            q1 += wt * a1
            q2 += wt * a2
            r0 += wt * b0
            r1 += wt * b1
            r2 += wt * b2
            qx0 += gx * a0
            qx1 += gx * a1
            qx2 += gx * a2
            qy0 += gy * a0
            qy1 += gy * a1
            qy2 += gy * a2
            rx0 += gx * b0
            rx1 += gx * b1
            rx2 += gx * b2
            ry0 += gy * b0
            ry1 += gy * b1
            ry2 += gy * b2
    if total <= 1e-9:
        return (0, q0, q1, q2, qx0, qx1, qx2, qy0, qy1, qy2, r0, r1, r2, rx0, rx1, rx2,
                ry0, ry1, ry2)
    inv = 1.0 / total
    q0, q1, q2 = q0 * inv, q1 * inv, q2 * inv
    qx0, qx1, qx2 = (qx0 - q0 * tx) * inv, (qx1 - q1 * tx) * inv, (qx2 - q2 * tx) * inv
    qy0, qy1, qy2 = (qy0 - q0 * ty) * inv, (qy1 - q1 * ty) * inv, (qy2 - q2 * ty) * inv
    inv = 1.0 / math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    r0, r1, r2 = r0 * inv, r1 * inv, r2 * inv
    along = r0 * rx0 + r1 * rx1 + r2 * rx2
    rx0, rx1, rx2 = (rx0 - r0 * along) * inv, (rx1 - r1 * along) * inv, (rx2 - r2 * along) * inv
    along = r0 * ry0 + r1 * ry1 + r2 * ry2
    ry0, ry1, ry2 = (ry0 - r0 * along) * inv, (ry1 - r1 * along) * inv, (ry2 - r2 * along) * inv
    return (corners, q0, q1, q2, qx0, qx1, qx2, qy0, qy1, qy2, r0, r1, r2, rx0, rx1, rx2,
            ry0, ry1, ry2)


@njit(cache=True)
def _walk(p, owner, part, q, r, sx, sy, iterations):
    """Gauss-Newton from screen point (sx, sy) toward the reflection point of p: (status,
    Q x, y, z). The Jacobian of c(s) = unit(P - Q(s)) - R(s) is analytic, from one sample
    and its derivatives (_sample_slope): dc = -(dQ - u (u.dQ)) / |P - Q| - dR, u = unit(P -
    Q). EXACT with Q there; BOUNDARY where the walk leaves the part (the reflection lies
    past a silhouette, or on another part): then the last step is taken on the linear model
    from the last point inside, Q extrapolated along its screen derivatives, so that
    polygons reaching out there stretch past the part's edge (and are masked) as exact ones
    would; NONE if the part was never sampled (Q meaningless). One _step at a time (_refine
    runs the same steps, _LANES walks side by side: _advance)."""
    status = NONE
    e0 = e1 = e2 = 0.0  # Q at the end (extrapolated, unless exact)
    r0 = r1 = r2 = 0.0  # R at the last point inside
    for _ in range(iterations):
        go, sx, sy, status, e0, e1, e2, r0, r1, r2 = _step(
            p[0], p[1], p[2], owner, part, q, r, sx, sy, status, e0, e1, e2, r0, r1, r2)
        if not go:
            break
    return _walk_end(p[0], p[1], p[2], status, e0, e1, e2, r0, r1, r2)


@njit(cache=True, inline="always")
def _walk_end(p0, p1, p2, status, e0, e1, e2, r0, r1, r2):
    """A walk's answer (status, Q) from its last state."""
    if status == EXACT and (p0 - e0) * r0 + (p1 - e1) * r1 + (p2 - e2) * r2 <= 0.0:
        status = BOUNDARY  # on the line of the ray, but behind its start
    return status, e0, e1, e2


@njit(cache=True, inline="always")
def _step(p0, p1, p2, owner, part, q, r, sx, sy, status, e0, e1, e2, r0, r1, r2):
    """One Gauss-Newton step of _walk from screen point (sx, sy) with the walk's state
    (status, end e, last R): (go on, next sx, sy, status, e, R)."""
    h, w = owner.shape
    stop = (False, sx, sy, status, e0, e1, e2, r0, r1, r2)
    if not (0.0 <= sx < w and 0.0 <= sy < h):
        return stop
    (corners, q0, q1, q2, qx0, qx1, qx2, qy0, qy1, qy2, s0, s1, s2, rx0, rx1, rx2, ry0,
     ry1, ry2) = _sample_slope(owner, part, q, r, sx, sy)
    if corners == 0:
        return stop
    d0 = p0 - q0
    d1 = p1 - q1
    d2 = p2 - q2
    dd = d0 * d0 + d1 * d1 + d2 * d2
    if dd <= 0.0:
        return stop
    if corners == 1:  # a lone corner of the part: no direction to go
        return False, sx, sy, BOUNDARY, q0, q1, q2, s0, s1, s2
    inv = 1.0 / math.sqrt(dd)
    u0, u1, u2 = d0 * inv, d1 * inv, d2 * inv
    c0, c1, c2 = u0 - s0, u1 - s1, u2 - s2
    # Jacobian columns (per pixel) and the 2x2 normal equations
    along = u0 * qx0 + u1 * qx1 + u2 * qx2
    jx0 = (u0 * along - qx0) * inv - rx0
    jx1 = (u1 * along - qx1) * inv - rx1
    jx2 = (u2 * along - qx2) * inv - rx2
    along = u0 * qy0 + u1 * qy1 + u2 * qy2
    jy0 = (u0 * along - qy0) * inv - ry0
    jy1 = (u1 * along - qy1) * inv - ry1
    jy2 = (u2 * along - qy2) * inv - ry2
    a00 = jx0 * jx0 + jx1 * jx1 + jx2 * jx2
    a01 = jx0 * jy0 + jx1 * jy1 + jx2 * jy2
    a11 = jy0 * jy0 + jy1 * jy1 + jy2 * jy2
    g0 = jx0 * c0 + jx1 * c1 + jx2 * c2
    g1 = jy0 * c0 + jy1 * c1 + jy2 * c2
    det = a00 * a11 - a01 * a01
    trace = a00 + a11
    if det > 1e-12 * trace * trace:
        inv = 1.0 / det
        dx = (a01 * g1 - a11 * g0) * inv
        dy = (a01 * g0 - a00 * g1) * inv
    elif trace > 1e-30:
        # one direction only (a cell with one row or column of the part's corners):
        # the least-norm step, along the gradient, which lies in the Jacobian's range
        inv = 1.0 / trace
        dx = -g0 * inv
        dy = -g1 * inv
    else:
        return False, sx, sy, BOUNDARY, q0, q1, q2, s0, s1, s2
    step = dx * dx + dy * dy
    if step > 64.0:  # a trust region: no jumps across the part
        scale = 8.0 / math.sqrt(step)
        dx *= scale
        dy *= scale
    e0 = q0 + qx0 * dx + qy0 * dy
    e1 = q1 + qx1 * dx + qy1 * dy
    e2 = q2 + qx2 * dx + qy2 * dy
    if step < 1e-6:  # under a thousandth of a pixel
        # EXACT at the linear model's zero, the step's end; else a local minimum
        done = EXACT if c0 * c0 + c1 * c1 + c2 * c2 <= 1e-4 else BOUNDARY
        return False, sx, sy, done, e0, e1, e2, s0, s1, s2
    return True, sx + dx, sy + dy, BOUNDARY, e0, e1, e2, s0, s1, s2


_CHUNK = 64  # points claimed at a time by a thread in _refine
_LANES = 64  # walks stepped together by a thread (16: 8% slower, 128: 7%)


@njit(cache=True, parallel=True)
def _refine(points, seeds, owner, parts, q, r, eye, iterations, retry, reach, out, ok,
            threads):
    """refine_parts' search, point by point (point i in part parts[i] of `owner`). Walks
    take 1 to 2 x `iterations` steps, so points go in chunks claimed by whichever thread
    is free (parallel.py); each point's answer is its own, whoever finds it. A thread runs
    _LANES walks together, a step of each at a time, in three passes over the lanes: each
    lane's cell corners fetched (_gather), the steps' arithmetic for all lanes at once
    (_advance: no branches, so that it runs on several lanes per instruction), and each
    lane's walk ended or continued (_after_steps). A lane whose walk ends takes the point's
    retry, or the next point (claiming a new chunk when its own is done)."""
    n = points.shape[0]
    chunks = (n + _CHUNK - 1) // _CHUNK
    claimed = counter()
    for _worker in prange(min(threads, chunks)):
        lanes = _lane_arrays(_LANES)
        _walk_lanes(points, seeds, owner, parts, q, r, eye, iterations, retry, reach, out,
                    ok, chunks, claimed, lanes)
    for c in prange(chunks):
        _finish_all(c * _CHUNK, min(n, (c + 1) * _CHUNK), points, eye, out, ok)


@njit(cache=True)
def _lane_arrays(count):
    """A thread's lane arrays: per lane point (-1: idle), phase (0: from the seed, 1: the
    retry), steps taken, the first walk's answer (4); the walk's state: sx, sy, status,
    end e (3), last R (3), the point (3); the cell corners fetched for the next step: Q and
    R of each of the 4 corners (24 rows, 0 where the corner is not the part's), their
    masks (4 rows, 1 or 0), the cell fractions (2 rows); the step's `go` (1 row); the
    chunk (next point, end) (2)."""
    lane_k = np.empty(count, np.int64)
    phase = np.empty(count, np.int64)
    steps = np.empty(count, np.int64)
    first = np.empty((4, count))
    values = np.zeros(_ROWS * count)
    chunk = np.zeros(2, np.int64)
    return lane_k, phase, steps, first, values, chunk


# rows of the lanes' values (lane j of row m at m * _LANES + j, the rows a constant apart,
# so that the compiler sees the rows of _advance's loop do not overlap): a lane's state
_SX, _SY, _ST, _E, _R, _P = 0, 1, 2, 3, 6, 9
# its fetched cell: Q, R of corner c at rows _Q + 6c .. _Q + 6c + 5, its mask at _MASK + c,
# the cell fractions ax, ay; the step's go
_Q = 12
_MASK, _AX, _AY, _GO = _Q + 24, _Q + 28, _Q + 29, _Q + 30
_ROWS = _Q + 31


@njit(cache=True)
def _walk_lanes(points, seeds, owner, parts, q, r, eye, iterations, retry, reach, out, ok,
                chunks, claimed, lanes):
    """A worker of _refine: its lanes' walks until no chunk is left."""
    lane_k, phase, steps, first, values, chunk = lanes
    count = lane_k.shape[0]
    chunk[0] = chunk[1] = 0
    active = 0
    for j in range(count):
        _next_point(j, points, seeds, retry, chunks, claimed, lanes)
        active += lane_k[j] >= 0
    while active > 0:
        _gather(owner, parts, q, r, lane_k, values)
        _advance(values)
        active = _after_steps(points, seeds, eye, iterations, retry, reach, out, ok, chunks,
                              claimed, lanes)


@njit(cache=True)
def _gather(owner, parts, q, r, lane_k, values):
    """For each lane: the four pixel centers around its screen point (sx, sy), Q and R of
    each that is its part's (else 0 and mask 0), and the fractions ax, ay of the point in
    the cell, as _sample_slope reads them; all masks 0 for an idle lane or a point off the
    screen (_step's stop)."""
    h, w = owner.shape
    for j in range(lane_k.shape[0]):
        i = lane_k[j]
        sx = values[_SX * _LANES + j]
        sy = values[_SY * _LANES + j]
        if i < 0 or not (0.0 <= sx < w and 0.0 <= sy < h):
            for m in range(_MASK, _MASK + 4):
                values[m * _LANES + j] = 0.0
            continue
        part = parts[i]
        fx = sx - 0.5
        fy = sy - 0.5
        x0 = int(math.floor(fx))
        y0 = int(math.floor(fy))
        values[_AX * _LANES + j] = fx - x0
        values[_AY * _LANES + j] = fy - y0
        for dy in range(2):
            y = y0 + dy
            yin = 0 <= y < h
            yc = min(max(y, 0), h - 1)
            for dx in range(2):
                c = 2 * dy + dx
                x = x0 + dx
                xc = min(max(x, 0), w - 1)
                # the corner's values, or zeros where it is not the part's: selects, not
                # branches (the part's edge is crossed often, unpredictably)
                m = yin and 0 <= x < w and owner[yc, xc] == part
                row = (_Q + 6 * c) * _LANES + j
                values[(_MASK + c) * _LANES + j] = 1.0 if m else 0.0
                values[row] = q[yc, xc, 0] if m else 0.0
                values[row + _LANES] = q[yc, xc, 1] if m else 0.0
                values[row + 2 * _LANES] = q[yc, xc, 2] if m else 0.0
                values[row + 3 * _LANES] = r[yc, xc, 0] if m else 0.0
                values[row + 4 * _LANES] = r[yc, xc, 1] if m else 0.0
                values[row + 5 * _LANES] = r[yc, xc, 2] if m else 0.0


@njit(cache=True, error_model="numpy")
def _advance(values):
    """_step for every lane at once from the corners _gather fetched: the same arithmetic
    in the same order (a corner not the part's adds zeros, which leaves every sum as it
    is: none is ever -0), each case's answer worked and the lane's picked by selects, so
    the loop over the lanes has no branch to keep it from running several lanes per
    instruction. Writes the lane's state (sx, sy, status, e, R) and go (1 or 0)."""
    for j in range(_LANES):
        ax = values[_AX * _LANES + j]
        ay = values[_AY * _LANES + j]
        bx = 1.0 - ax
        by = 1.0 - ay
        total = tx = ty = 0.0
        q0 = q1 = q2 = r0 = r1 = r2 = 0.0
        qx0 = qx1 = qx2 = rx0 = rx1 = rx2 = 0.0
        qy0 = qy1 = qy2 = ry0 = ry1 = ry2 = 0.0
        # the corners in _sample_slope's order, written out (a loop over them would keep
        # the loop over the lanes from running several lanes at once)
        corners = 0.0
        wt = bx * by
        gx = -by
        gy = -bx
        m = values[(_MASK + 0) * _LANES + j]
        a0 = values[(_Q + 0) * _LANES + j]
        a1 = values[(_Q + 1) * _LANES + j]
        a2 = values[(_Q + 2) * _LANES + j]
        b0 = values[(_Q + 3) * _LANES + j]
        b1 = values[(_Q + 4) * _LANES + j]
        b2 = values[(_Q + 5) * _LANES + j]
        corners += m
        total += wt * m
        tx += gx * m
        ty += gy * m
        q0 += wt * a0
        q1 += wt * a1
        q2 += wt * a2
        r0 += wt * b0
        r1 += wt * b1
        r2 += wt * b2
        qx0 += gx * a0
        qx1 += gx * a1
        qx2 += gx * a2
        qy0 += gy * a0
        qy1 += gy * a1
        qy2 += gy * a2
        rx0 += gx * b0
        rx1 += gx * b1
        rx2 += gx * b2
        ry0 += gy * b0
        ry1 += gy * b1
        ry2 += gy * b2
        wt = ax * by
        gx = by
        gy = -ax
        m = values[(_MASK + 1) * _LANES + j]
        a0 = values[(_Q + 6) * _LANES + j]
        a1 = values[(_Q + 7) * _LANES + j]
        a2 = values[(_Q + 8) * _LANES + j]
        b0 = values[(_Q + 9) * _LANES + j]
        b1 = values[(_Q + 10) * _LANES + j]
        b2 = values[(_Q + 11) * _LANES + j]
        corners += m
        total += wt * m
        tx += gx * m
        ty += gy * m
        q0 += wt * a0
        q1 += wt * a1
        q2 += wt * a2
        r0 += wt * b0
        r1 += wt * b1
        r2 += wt * b2
        qx0 += gx * a0
        qx1 += gx * a1
        qx2 += gx * a2
        qy0 += gy * a0
        qy1 += gy * a1
        qy2 += gy * a2
        rx0 += gx * b0
        rx1 += gx * b1
        rx2 += gx * b2
        ry0 += gy * b0
        ry1 += gy * b1
        ry2 += gy * b2
        wt = bx * ay
        gx = -ay
        gy = bx
        m = values[(_MASK + 2) * _LANES + j]
        a0 = values[(_Q + 12) * _LANES + j]
        a1 = values[(_Q + 13) * _LANES + j]
        a2 = values[(_Q + 14) * _LANES + j]
        b0 = values[(_Q + 15) * _LANES + j]
        b1 = values[(_Q + 16) * _LANES + j]
        b2 = values[(_Q + 17) * _LANES + j]
        corners += m
        total += wt * m
        tx += gx * m
        ty += gy * m
        q0 += wt * a0
        q1 += wt * a1
        q2 += wt * a2
        r0 += wt * b0
        r1 += wt * b1
        r2 += wt * b2
        qx0 += gx * a0
        qx1 += gx * a1
        qx2 += gx * a2
        qy0 += gy * a0
        qy1 += gy * a1
        qy2 += gy * a2
        rx0 += gx * b0
        rx1 += gx * b1
        rx2 += gx * b2
        ry0 += gy * b0
        ry1 += gy * b1
        ry2 += gy * b2
        wt = ax * ay
        gx = ay
        gy = ax
        m = values[(_MASK + 3) * _LANES + j]
        a0 = values[(_Q + 18) * _LANES + j]
        a1 = values[(_Q + 19) * _LANES + j]
        a2 = values[(_Q + 20) * _LANES + j]
        b0 = values[(_Q + 21) * _LANES + j]
        b1 = values[(_Q + 22) * _LANES + j]
        b2 = values[(_Q + 23) * _LANES + j]
        corners += m
        total += wt * m
        tx += gx * m
        ty += gy * m
        q0 += wt * a0
        q1 += wt * a1
        q2 += wt * a2
        r0 += wt * b0
        r1 += wt * b1
        r2 += wt * b2
        qx0 += gx * a0
        qx1 += gx * a1
        qx2 += gx * a2
        qy0 += gy * a0
        qy1 += gy * a1
        qy2 += gy * a2
        rx0 += gx * b0
        rx1 += gx * b1
        rx2 += gx * b2
        ry0 += gy * b0
        ry1 += gy * b1
        ry2 += gy * b2
        inv = 1.0 / total
        q0, q1, q2 = q0 * inv, q1 * inv, q2 * inv
        qx0, qx1, qx2 = (qx0 - q0 * tx) * inv, (qx1 - q1 * tx) * inv, (qx2 - q2 * tx) * inv
        qy0, qy1, qy2 = (qy0 - q0 * ty) * inv, (qy1 - q1 * ty) * inv, (qy2 - q2 * ty) * inv
        inv = 1.0 / math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
        s0, s1, s2 = r0 * inv, r1 * inv, r2 * inv
        along = s0 * rx0 + s1 * rx1 + s2 * rx2
        rx0, rx1, rx2 = (rx0 - s0 * along) * inv, (rx1 - s1 * along) * inv, \
            (rx2 - s2 * along) * inv
        along = s0 * ry0 + s1 * ry1 + s2 * ry2
        ry0, ry1, ry2 = (ry0 - s0 * along) * inv, (ry1 - s1 * along) * inv, \
            (ry2 - s2 * along) * inv
        p0 = values[_P * _LANES + j]
        p1 = values[(_P + 1) * _LANES + j]
        p2 = values[(_P + 2) * _LANES + j]
        d0 = p0 - q0
        d1 = p1 - q1
        d2 = p2 - q2
        dd = d0 * d0 + d1 * d1 + d2 * d2
        inv = 1.0 / math.sqrt(dd)
        u0, u1, u2 = d0 * inv, d1 * inv, d2 * inv
        c0, c1, c2 = u0 - s0, u1 - s1, u2 - s2
        along = u0 * qx0 + u1 * qx1 + u2 * qx2
        jx0 = (u0 * along - qx0) * inv - rx0
        jx1 = (u1 * along - qx1) * inv - rx1
        jx2 = (u2 * along - qx2) * inv - rx2
        along = u0 * qy0 + u1 * qy1 + u2 * qy2
        jy0 = (u0 * along - qy0) * inv - ry0
        jy1 = (u1 * along - qy1) * inv - ry1
        jy2 = (u2 * along - qy2) * inv - ry2
        a00 = jx0 * jx0 + jx1 * jx1 + jx2 * jx2
        a01 = jx0 * jy0 + jx1 * jy1 + jx2 * jy2
        a11 = jy0 * jy0 + jy1 * jy1 + jy2 * jy2
        g0 = jx0 * c0 + jx1 * c1 + jx2 * c2
        g1 = jy0 * c0 + jy1 * c1 + jy2 * c2
        det = a00 * a11 - a01 * a01
        trace = a00 + a11
        inv = 1.0 / det
        inv_t = 1.0 / trace
        newton = det > 1e-12 * trace * trace
        gradient = trace > 1e-30
        dx = (a01 * g1 - a11 * g0) * inv if newton else -g0 * inv_t
        dy = (a01 * g0 - a00 * g1) * inv if newton else -g1 * inv_t
        step = dx * dx + dy * dy
        scale = 8.0 / math.sqrt(step)
        far = step > 64.0  # a trust region: no jumps across the part
        dx = dx * scale if far else dx
        dy = dy * scale if far else dy
        e0 = q0 + qx0 * dx + qy0 * dy
        e1 = q1 + qx1 * dx + qy1 * dy
        e2 = q2 + qx2 * dx + qy2 * dy
        small = step < 1e-6
        done = float(EXACT) if c0 * c0 + c1 * c1 + c2 * c2 <= 1e-4 else float(BOUNDARY)
        # the cases of _step, in its order: stop (the state kept), a lone corner, no
        # direction, converged, a step on
        keep = total <= 1e-9 or dd <= 0.0
        lone = corners == 1.0
        stuck = not (newton or gradient)
        ends = lone or stuck  # at Q, R
        go = not (keep or ends or small)
        e0 = q0 if ends else e0
        e1 = q1 if ends else e1
        e2 = q2 if ends else e2
        st = done if small else float(BOUNDARY)
        sx = values[_SX * _LANES + j]
        sy = values[_SY * _LANES + j]
        values[_SX * _LANES + j] = sx + dx if go else sx
        values[_SY * _LANES + j] = sy + dy if go else sy
        at = _ST * _LANES + j
        values[at] = values[at] if keep else (float(BOUNDARY) if ends else st)
        for m, v in ((_E, e0), (_E + 1, e1), (_E + 2, e2), (_R, s0), (_R + 1, s1),
                     (_R + 2, s2)):
            at = m * _LANES + j
            values[at] = values[at] if keep else v
        values[_GO * _LANES + j] = 1.0 if go else 0.0


@njit(cache=True)
def _after_steps(points, seeds, eye, iterations, retry, reach, out, ok, chunks, claimed,
                 lanes):
    """Each busy lane after its step: the walk goes on, or ends: then the point's retry
    (refine_virtual's rule), or its answer (_finish) and the lane's next point. Returns
    how many lanes are busy."""
    lane_k, phase, steps, first, values, chunk = lanes
    active = 0
    for j in range(lane_k.shape[0]):
        i = lane_k[j]
        if i < 0:
            continue
        steps[j] += 1
        if values[_GO * _LANES + j] != 0.0 and steps[j] < iterations:
            active += 1
            continue
        e = _E * _LANES + j
        at = _R * _LANES + j
        st, e0, e1, e2 = _walk_end(
            points[i, 0], points[i, 1], points[i, 2], int(values[_ST * _LANES + j]),
            values[e], values[e + _LANES], values[e + 2 * _LANES], values[at],
            values[at + _LANES], values[at + 2 * _LANES])
        if phase[j] == 0 and (st == NONE or (st == BOUNDARY and reach[i])) \
                and np.isfinite(retry[i, 0]):
            first[0, j], first[1, j], first[2, j], first[3, j] = st, e0, e1, e2
            _begin(j, 1, retry[i, 0], retry[i, 1], phase, steps, values)
            active += 1
            continue
        if phase[j] == 1:
            was = int(first[0, j])
            if not (st == EXACT or (was == NONE and st != NONE)):
                st, e0, e1, e2 = was, first[1, j], first[2, j], first[3, j]
        if st != NONE:  # Q at the end: _finish_all makes it the virtual vertex
            out[i, 0], out[i, 1], out[i, 2] = e0, e1, e2
            ok[i] = st
        _next_point(j, points, seeds, retry, chunks, claimed, lanes)
        active += lane_k[j] >= 0
    return active


@njit(cache=True, inline="always")
def _begin(j, which, sx, sy, phase, steps, values):
    """Lane j starts a walk (phase `which`) at screen point (sx, sy)."""
    phase[j] = which
    steps[j] = 0
    values[_SX * _LANES + j] = sx
    values[_SY * _LANES + j] = sy
    values[_ST * _LANES + j] = NONE
    for m in range(_E, _P):
        values[m * _LANES + j] = 0.0


@njit(cache=True)
def _next_point(j, points, seeds, retry, chunks, claimed, lanes):
    """Lane j takes the next point of its chunk (claiming the next chunk when it is done)
    that has a walk to take (from its seed, else its retry, the first walk then NONE);
    points with neither stay NONE. lane_k[j] -1 if none is left."""
    lane_k, phase, steps, first, values, chunk = lanes
    n = points.shape[0]
    while True:
        if chunk[0] >= chunk[1]:
            c = claim(claimed)
            if c >= chunks:
                chunk[0] = chunk[1] = n
                lane_k[j] = -1
                return
            chunk[0] = c * _CHUNK
            chunk[1] = min(n, (c + 1) * _CHUNK)
        i = chunk[0]
        chunk[0] += 1
        if np.isfinite(seeds[i, 0]) and np.isfinite(seeds[i, 1]):
            _take(j, i, points, lane_k, values)
            _begin(j, 0, seeds[i, 0], seeds[i, 1], phase, steps, values)
            return
        if np.isfinite(retry[i, 0]):
            _take(j, i, points, lane_k, values)
            first[0, j] = NONE
            _begin(j, 1, retry[i, 0], retry[i, 1], phase, steps, values)
            return


@njit(cache=True, inline="always")
def _take(j, i, points, lane_k, values):
    """Lane j takes point i."""
    lane_k[j] = i
    values[_P * _LANES + j] = points[i, 0]
    values[(_P + 1) * _LANES + j] = points[i, 1]
    values[(_P + 2) * _LANES + j] = points[i, 2]


@njit(cache=True, error_model="numpy")
def _finish_all(k0, k1, points, eye, out, ok):
    """Points k0 .. k1-1's virtual vertices (_finish) from their walks' answers: out[k] the
    end Q where ok[k] (the status) is not NONE."""
    for k in range(k0, k1):
        e0, e1, e2 = out[k, 0], out[k, 1], out[k, 2]
        d0, d1, d2 = points[k, 0] - e0, points[k, 1] - e1, points[k, 2] - e2
        v0, v1, v2 = e0 - eye[0], e1 - eye[1], e2 - eye[2]
        le = math.sqrt(v0 ** 2 + v1 ** 2 + v2 ** 2)
        lp = math.sqrt(d0 ** 2 + d1 ** 2 + d2 ** 2)
        found = ok[k] != NONE
        out[k, 0] = eye[0] + v0 / le * (le + lp) if found else e0
        out[k, 1] = eye[1] + v1 / le * (le + lp) if found else e1
        out[k, 2] = eye[2] + v2 / le * (le + lp) if found else e2
