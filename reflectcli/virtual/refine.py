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
from ..raster.rasterize import recover_barycentrics
from .tiles import owner_plane


def reflector_grid(triangle: np.ndarray, b1: np.ndarray, b2: np.ndarray, corners: np.ndarray,
                   normals: np.ndarray, eye: np.ndarray,
                   out: tuple[np.ndarray | None, np.ndarray] | None = None):
    """Per pixel of a reflector-only item buffer: Q (H, W, 3) world point, R (H, W, 3) unit
    reflected direction of the eye ray (interpolated normal, two-sided); pixels the reflector
    does not cover hold NaN. `out`: (Q, R) (H, W, 3) float64 arrays to fill instead of new
    ones; Q None: R only (Q is returned as None)."""
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
    runs the same steps, several walks side by side)."""
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
_LANES = 4  # walks run side by side by a thread


@njit(cache=True, parallel=True)
def _refine(points, seeds, owner, parts, q, r, eye, iterations, retry, reach, out, ok,
            threads):
    """refine_parts' search, point by point (point i in part parts[i] of `owner`). Walks
    take 1 to 2 x `iterations` steps, so points go in chunks claimed by whichever thread
    is free (parallel.py); each point's answer is its own, whoever finds it. A thread runs
    _LANES walks side by side, a step of each in turn: a step is a chain of divisions and
    square roots, each waiting on the last, and the steps of other walks fill those waits.
    A lane whose walk ends takes the point's retry, or the chunk's next point."""
    n = points.shape[0]
    chunks = (n + _CHUNK - 1) // _CHUNK
    claimed = counter()
    for _worker in prange(min(threads, chunks)):
        # per lane: point (-1: idle), phase (0: from the seed, 1: the retry), steps taken,
        # the first walk's answer; the walk's state: (sx, sy, status, e, R)
        lane_k = np.empty(_LANES, np.int64)
        phase = np.empty(_LANES, np.int64)
        steps = np.empty(_LANES, np.int64)
        first = np.empty((_LANES, 4))
        state = np.empty((_LANES, 9))
        status = np.empty(_LANES, np.int64)
        while True:
            c = claim(claimed)
            if c >= chunks:
                break
            k = c * _CHUNK
            end = min(n, (c + 1) * _CHUNK)
            active = 0
            for j in range(_LANES):
                k = _start(j, k, end, points, seeds, retry, out, ok, eye, lane_k, phase, steps,
                           first, state, status)
                active += lane_k[j] >= 0
            while active > 0:
                for j in range(_LANES):
                    i = lane_k[j]
                    if i < 0:
                        continue
                    go, sx, sy, st, e0, e1, e2, r0, r1, r2 = _step(
                        points[i, 0], points[i, 1], points[i, 2], owner, parts[i], q, r,
                        state[j, 0], state[j, 1], status[j], state[j, 2], state[j, 3],
                        state[j, 4], state[j, 5], state[j, 6], state[j, 7])
                    steps[j] += 1
                    status[j] = st
                    state[j, 0], state[j, 1] = sx, sy
                    state[j, 2], state[j, 3], state[j, 4] = e0, e1, e2
                    state[j, 5], state[j, 6], state[j, 7] = r0, r1, r2
                    if go and steps[j] < iterations:
                        continue
                    st, e0, e1, e2 = _walk_end(points[i, 0], points[i, 1], points[i, 2], st,
                                               e0, e1, e2, r0, r1, r2)
                    if phase[j] == 0 and (st == NONE or (st == BOUNDARY and reach[i])) \
                            and np.isfinite(retry[i, 0]):
                        first[j, 0], first[j, 1], first[j, 2], first[j, 3] = st, e0, e1, e2
                        _begin(j, 1, retry[i, 0], retry[i, 1], phase, steps, state, status)
                        continue
                    if phase[j] == 1:
                        was = int(first[j, 0])
                        if not (st == EXACT or (was == NONE and st != NONE)):
                            st, e0, e1, e2 = was, first[j, 1], first[j, 2], first[j, 3]
                    _finish(i, points, st, e0, e1, e2, eye, out, ok)
                    k = _start(j, k, end, points, seeds, retry, out, ok, eye, lane_k, phase,
                               steps, first, state, status)
                    active -= lane_k[j] < 0


@njit(cache=True, inline="always")
def _begin(j, which, sx, sy, phase, steps, state, status):
    """Lane j starts a walk (phase `which`) at screen point (sx, sy)."""
    phase[j] = which
    steps[j] = 0
    status[j] = NONE
    state[j, 0], state[j, 1] = sx, sy
    for m in range(2, 9):
        state[j, m] = 0.0


@njit(cache=True, inline="always")
def _start(j, k, end, points, seeds, retry, out, ok, eye, lane_k, phase, steps, first, state,
           status):
    """Lane j takes the next point from k on (below `end`) that has a walk to take (from its
    seed, else its retry, the first walk then NONE); points with neither stay NONE. Returns
    the next k; lane_k[j] -1 if none is left."""
    while k < end:
        i = k
        k += 1
        if np.isfinite(seeds[i, 0]) and np.isfinite(seeds[i, 1]):
            lane_k[j] = i
            _begin(j, 0, seeds[i, 0], seeds[i, 1], phase, steps, state, status)
            return k
        if np.isfinite(retry[i, 0]):
            lane_k[j] = i
            first[j, 0] = NONE
            _begin(j, 1, retry[i, 0], retry[i, 1], phase, steps, state, status)
            return k
    lane_k[j] = -1
    return k


@njit(cache=True, inline="always")
def _finish(k, points, status, e0, e1, e2, eye, out, ok):
    """Point k's virtual vertex from its walks' answer (status, Q) into out[k] and ok[k]."""
    if status == NONE:
        return
    d0, d1, d2 = points[k, 0] - e0, points[k, 1] - e1, points[k, 2] - e2
    v0, v1, v2 = e0 - eye[0], e1 - eye[1], e2 - eye[2]
    le = math.sqrt(v0 ** 2 + v1 ** 2 + v2 ** 2)
    lp = math.sqrt(d0 ** 2 + d1 ** 2 + d2 ** 2)
    out[k, 0] = eye[0] + v0 / le * (le + lp)
    out[k, 1] = eye[1] + v1 / le * (le + lp)
    out[k, 2] = eye[2] + v2 / le * (le + lp)
    ok[k] = status
