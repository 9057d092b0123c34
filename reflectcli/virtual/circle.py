"""Exact virtual vertices on spheres and cylinders (numba, world space): the reflection point
on a circle, solved for blocks of points at once.

Sphere (`method = "sphere"`): the reflection point J of a scene point Q seen from the eye E
lies on the great circle through E, Q and the center C (the plane of the three), on the arc
between the directions of E and Q. With n(theta) the unit normal at angle theta from C->E
in that plane, the law of reflection says the unit vectors from J to E and to Q are mirror
images about n: f(theta) = n x u_E + n x u_Q = 0 (2-D cross products). f > 0 at theta = 0
and < 0 at the direction of Q, so the root is bracketed (`_circle_reflection`). Q' is Q
mirrored across the tangent plane at J. A hidden Q (the line of sight to it enters the
reflector first) is mirrored across the tangent plane where the line of sight enters, like
the paper's hidden map: its doubly virtual vertex lies in front of the reflector and only
closes polygons.

Cylinder (`method = "extrusion"`): the normals lie in planes perpendicular to the axis, so
the law of reflection holds for the projections onto such a plane: the same circle problem
in the cross-section, and Q' is Q mirrored across the plane through the axis direction and
J. Points inside the reflector keep Q' = Q.

Speed: one search is a chain of square roots and divisions, each waiting for the last, so a
point at a time the core idles (about 175 ns a point). `_blocks` runs BLOCK points side by
side through the same steps, in loops without branches that the compiler vectorises: the
set-up, then `VECTOR_STEPS` safeguarded Newton steps (a point that has converged keeps its
answer), then the points still searching packed together and stepped side by side again,
the converged ones taken out after each step (up to TAIL_STEPS steps: on four-spheres a
third of the points converge in 3 steps, a quarter in 4, a tenth need 6 to 13; stepping
every point 5 times and the rest one at a time took 40% longer), then the mirroring. The
few points still searching after those continue one at a time from where they stand
(`_circle_newton`), so every point takes exactly the steps, in the same floating-point
operations, that `_circle_reflection` alone takes: the bytes do not depend on the
blocking.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

from ..parallel import claim, counter

BLOCK = 256  # points set side by side
VECTOR_STEPS = 3  # Newton steps taken side by side (about 4 evaluations converge a point)
# more steps side by side for the points left searching after those (VECTOR_STEPS +
# TAIL_STEPS < 100, the search's budget: the last points continue in _circle_newton)
TAIL_STEPS = 12

# per-point state in a block
_SEARCHING, _DONE, _NORMAL, _SAME, _SCALAR = 0, 1, 2, 3, 4


@njit(cache=True, inline="always", error_model="numpy")
def _circle_law(nx, ny, ex, ey, qx, qy, r):
    """(f(theta), f'(theta)) at the unit normal n = (cos theta, sin theta), with
    f = n x u_E + n x u_Q: positive before the reflection point, negative after. For a unit
    u_P from J = r n to P at distance L_P, with n x u and n . u the 2-D cross and dot
    products: d/dtheta (n x u_P) = -(n . u_P) - (r / L_P) (1 - (n x u_P)^2)."""
    jx, jy = r * nx, r * ny
    ux, uy = ex - jx, ey - jy
    length_e = math.sqrt(ux * ux + uy * uy)
    inv = 1.0 / length_e
    vx, vy = qx - jx, qy - jy
    length_q = max(math.sqrt(vx * vx + vy * vy), 1e-300)
    inv2 = 1.0 / length_q
    cross_e = (nx * uy - ny * ux) * inv
    cross_q = (nx * vy - ny * vx) * inv2
    slope = (-(nx * ux + ny * uy) * inv - r * inv * (1.0 - cross_e * cross_e)
             - (nx * vx + ny * vy) * inv2 - r * inv2 * (1.0 - cross_q * cross_q))
    return cross_e + cross_q, slope


@njit(cache=True, inline="always", error_model="numpy")
def _circle_start(ex, qx, qy, r):
    """The search's start for E = (ex, 0), Q = (qx, qy) with qy > 0, ex > 0: (mx, my, lo,
    hi, u), the bisector m of the bracket [0, phi_Q], the bracket in u = tan(theta -
    phi_Q / 2) (infinite if phi_Q = pi) and the first u (see _circle_reflection)."""
    lq = math.sqrt(qx * qx + qy * qy)
    cx, cy = qx / lq, qy / lq  # the normal at phi_Q (the bracket's far end)
    # the bisector m of [0, phi_Q] by the half-angle formulas (phi_Q in [0, pi])
    mx = math.sqrt(max(0.5 * (1.0 + cx), 0.0))
    my = math.sqrt(max(0.5 * (1.0 - cx), 0.0))
    px, py = -my, mx  # m_perp
    hi = my / mx if mx > 0.0 else np.inf
    lo = -hi
    height_e = max(math.sqrt(ex * ex) - r, 0.0)  # |E| (ey = 0), as the 2-D length
    height_q = max(lq - r, 0.0)
    w = 0.5 if height_e + height_q <= 0.0 else height_e / (height_e + height_q)
    gx, gy = (1.0 - w) + w * cx, w * cy  # the blend of the ends' normals (unnormalized)
    along = gx * mx + gy * my
    u = (gx * px + gy * py) / along if along > 0.0 else 0.0
    u = u if lo < u < hi else 0.0
    return mx, my, lo, hi, u


@njit(cache=True, inline="always", error_model="numpy")
def _newton_step(u, lo, hi, mx, my, ex, qx, qy, r):
    """One safeguarded Newton step from u: (state, u, lo, hi) with state _DONE (u is the
    answer: n(u) is the normal) or _SEARCHING (u the next point), written without branches
    so that a block of points takes it side by side. Needs a finite bracket where it
    bisects (_circle_newton handles an infinite one)."""
    px, py = -my, mx
    inv = 1.0 / math.sqrt(1.0 + u * u)
    nx, ny = (mx + u * px) * inv, (my + u * py) * inv
    f, slope = _circle_law(nx, ny, ex, 0.0, qx, qy, r)
    lo = u if f > 0.0 else lo
    hi = hi if f > 0.0 else u
    du = f / (slope * inv * inv) if slope != 0.0 else np.inf
    nxt = u - du
    nxt = nxt if lo < nxt < hi else 0.5 * (lo + hi)
    # a Newton step below 1e-8 rad leaves an error of order its square: done
    done = (f == 0.0) | (abs(nxt - u) * inv * inv < 1e-8) | ((hi - lo) * inv * inv < 1e-13)
    answer = u if f == 0.0 else nxt
    return (_DONE if done else _SEARCHING), answer, lo, hi


@njit(cache=True, inline="always", error_model="numpy")
def _normal(mx, my, u):
    """n(u) = (m + u m_perp) / sqrt(1 + u^2)."""
    inv = 1.0 / math.sqrt(1.0 + u * u)
    px, py = -my, mx
    return (mx + u * px) * inv, (my + u * py) * inv


@njit(cache=True, error_model="numpy")
def _circle_newton(u, lo, hi, mx, my, ex, qx, qy, r, steps):
    """The search of _circle_reflection from u inside the bracket (lo, hi), at most `steps`
    more evaluations: the unit normal (cos theta, sin theta) found (at the last point
    evaluated, if none converged)."""
    last = u
    for _ in range(steps):
        last = u
        if np.isfinite(lo) and np.isfinite(hi):
            state, nxt, lo, hi = _newton_step(u, lo, hi, mx, my, ex, qx, qy, r)
            if state == _DONE:
                return _normal(mx, my, nxt)
            u = nxt
            continue
        # an infinite bracket (phi_Q = pi): the same step, stepping out by 1 to bisect
        px, py = -my, mx
        inv = 1.0 / math.sqrt(1.0 + u * u)
        nx, ny = (mx + u * px) * inv, (my + u * py) * inv
        f, slope = _circle_law(nx, ny, ex, 0.0, qx, qy, r)
        if f == 0.0:
            return nx, ny
        if f > 0.0:
            lo = u
        else:
            hi = u
        du = f / (slope * inv * inv) if slope != 0.0 else np.inf
        nxt = u - du
        if not lo < nxt < hi:
            nxt = 0.5 * (lo + hi) if np.isfinite(lo) and np.isfinite(hi) else (
                u - 1.0 if np.isfinite(hi) else u + 1.0)
        if abs(nxt - u) * inv * inv < 1e-8 or (hi - lo) * inv * inv < 1e-13:
            return _normal(mx, my, nxt)
        u = nxt
    return _normal(mx, my, last)


@njit(cache=True, error_model="numpy")
def _circle_reflection(ex, qx, qy, r):
    """Unit normal (cos theta, sin theta) at the reflection point on a circle of radius r at
    the origin for E = (ex, 0) on the +x axis and Q = (qx, qy) with qy >= 0.

    The root of f on [0, phi_Q] is bracketed. Newton's method, kept inside the shrinking
    bracket (bisection whenever a step would leave it), on u = tan(theta - phi_Q / 2): the
    normal n(u) = (m + u m_perp) / sqrt(1 + u^2) around the bisector m of the bracket needs
    no trigonometry (d theta / du = 1 / (1 + u^2)). It starts from the blend of the bracket's
    end normals in the ratio of the two points' heights above the circle (right when they
    are equal, and at either end as one of them reaches the circle). About 4 evaluations of
    f, to about 1e-13 rad."""
    # the signs at the ends need no evaluation: at theta = 0, n x u_E = 0 and n x u_Q =
    # qy / |Q - J| > 0; at phi_Q, n x u_Q = 0 and n x u_E = -cy ex / |E - J| < 0
    if not (qy > 0.0 and ex > 0.0):
        return 1.0, 0.0
    mx, my, lo, hi, u = _circle_start(ex, qx, qy, r)
    return _circle_newton(u, lo, hi, mx, my, ex, qx, qy, r, 100)


def sphere_virtual_vertices(points: np.ndarray, eye: np.ndarray, center: np.ndarray,
                            radius: float) -> tuple[np.ndarray, np.ndarray]:
    """(virtual points (N, 3), hidden (N,) bool) for a sphere mirror."""
    points = np.ascontiguousarray(points, np.float64)
    out = np.empty(points.shape, np.float64)
    hidden = np.empty(points.shape[0], np.bool_)
    spheres_virtual_vertices(points, eye, np.asarray(center, np.float64).reshape(1, 3),
                             np.array([float(radius)]), np.array([0, points.shape[0]]), out,
                             hidden, block_scratch())
    return out, hidden


def spheres_virtual_vertices(points: np.ndarray, eye: np.ndarray, centers: np.ndarray,
                             radii: np.ndarray, starts: np.ndarray, out: np.ndarray,
                             hidden: np.ndarray, scratch: np.ndarray) -> None:
    """Into out (N, 3; float64, or float32: the same numbers rounded once as they are
    stored), hidden (N,): the virtual points of several sphere mirrors' points
    at once, points[starts[s]:starts[s + 1]] (N, 3 world, float64) reflected in sphere s
    (centers (S, 3), radii (S,)): one parallel region for every sphere of a frame, not one
    each. Each point's answer is the one `sphere_virtual_vertices` gives it alone.
    `scratch`: `block_scratch()`'s, or kept from an earlier call of the same thread count."""
    _blocks(points, np.asarray(eye, np.float64), centers, radii,
            np.ascontiguousarray(starts, np.int64), np.zeros(3), False, out, hidden, scratch)


def cylinder_virtual_vertices(points: np.ndarray, eye: np.ndarray, origin: np.ndarray,
                              axis: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """(virtual points (N, 3), hidden (N,) bool) for a cylinder mirror."""
    out = np.empty(points.shape, np.float64)
    hidden = np.empty(points.shape[0], np.bool_)
    a = np.asarray(axis, np.float64)
    _blocks(np.ascontiguousarray(points, np.float64), np.asarray(eye, np.float64),
            np.asarray(origin, np.float64).reshape(1, 3), np.array([float(radius)]),
            np.array([0, points.shape[0]]), a / np.linalg.norm(a), True, out, hidden,
            block_scratch())
    return out, hidden


def block_scratch() -> np.ndarray:
    """Per-thread block scratch for _blocks (a few tens of kilobytes)."""
    threads = max(1, numba.get_num_threads())
    return np.empty((threads, _ROWS, BLOCK))


# rows of a block's scratch (one array, rows BLOCK apart: the compiler sees they never
# overlap and vectorises the loops over them)
_QX, _QY, _QZ, _XX, _XY, _XZ, _YX, _YY, _YZ, _LE, _A, _B = range(12)
_MX, _MY, _LO, _HI, _U, _CT, _ST, _STATE, _HIDDEN = range(12, 21)
# the points still searching after VECTOR_STEPS, packed to the front (_TAIL_J: their
# columns in the block)
_TA, _TB, _TMX, _TMY, _TLO, _THI, _TU, _TSTATE, _TAIL_J = range(21, 30)
_ROWS = 30


@njit(cache=True, parallel=True, error_model="numpy")
def _blocks(points, eye, centers, radii, starts, axis, use_axis, out, hidden, scratch):
    """(Q', hidden) of every point, BLOCK points at a time (see the module docstring):
    points starts[s] .. starts[s + 1] - 1 on circle s (centers[s], radii[s]), a block never
    spanning two; `scratch` (workers, _ROWS, BLOCK): per-worker scratch. Blocks are claimed
    one at a time by whichever worker is free (parallel.py): a block's cost varies with how
    many of its points fall back to the one-at-a-time search, and on a shared machine a
    worker may lose its core. A point's answer never depends on its block or worker."""
    circles = radii.shape[0]
    first = np.empty(circles + 1, np.int64)  # each circle's first block (np.zeros: a parallel loop)
    first[0] = 0
    for s in range(circles):
        first[s + 1] = first[s] + (starts[s + 1] - starts[s] + BLOCK - 1) // BLOCK
    claimed = counter()
    for me in prange(scratch.shape[0]):
        s = 0
        while True:
            b = claim(claimed)
            if b >= first[circles]:
                break
            while b >= first[s + 1]:  # claims only grow: a worker's circle only advances
                s += 1
            i0 = starts[s] + (b - first[s]) * BLOCK
            count = min(starts[s + 1], i0 + BLOCK) - i0
            _block(points, i0, count, eye, centers[s], radii[s], axis, use_axis, scratch[me],
                   out, hidden)


@njit(cache=True, error_model="numpy")
def _block(points, i0, count, eye, center, r, axis, use_axis, s, out, hidden):
    """Points i0 .. i0 + count - 1: set-up, VECTOR_STEPS side by side, those left packed and
    stepped side by side, the last one at a time, mirroring. `s` (_ROWS, BLOCK): scratch (one
    array: loops that touch only it vectorise; the state is a row of it too)."""
    ex, ey, ez = eye[0] - center[0], eye[1] - center[1], eye[2] - center[2]
    if use_axis:  # project onto the cross-section plane
        de = ex * axis[0] + ey * axis[1] + ez * axis[2]
        ex, ey, ez = ex - de * axis[0], ey - de * axis[1], ez - de * axis[2]
    le = math.sqrt(ex * ex + ey * ey + ez * ez)
    xx, xy, xz = ex / le, ey / le, ez / le  # 2-D x axis: toward the eye
    s[_XX, :count] = xx
    s[_XY, :count] = xy
    s[_XZ, :count] = xz
    s[_LE, :count] = le
    for j in range(count):
        s[_QX, j] = points[i0 + j, 0] - center[0]
        s[_QY, j] = points[i0 + j, 1] - center[1]
        s[_QZ, j] = points[i0 + j, 2] - center[2]
    if use_axis:
        for j in range(count):
            dq = s[_QX, j] * axis[0] + s[_QY, j] * axis[1] + s[_QZ, j] * axis[2]
            s[_QX, j] = s[_QX, j] - dq * axis[0]
            s[_QY, j] = s[_QY, j] - dq * axis[1]
            s[_QZ, j] = s[_QZ, j] - dq * axis[2]
    # the set-up in three loops (one holding all of it is not vectorised)
    for j in range(count):
        qx, qy, qz = s[_QX, j], s[_QY, j], s[_QZ, j]
        lq = math.sqrt(qx * qx + qy * qy + qz * qz)
        same = (lq <= r) | (le <= r)
        a = qx * xx + qy * xy + qz * xz
        yx, yy, yz = qx - a * xx, qy - a * xy, qz - a * xz
        b = math.sqrt(yx * yx + yy * yy + yz * yz)
        on_line = b < 1e-12 * lq  # Q on the line through C and E
        s[_YX, j] = 0.0 if on_line else yx / b
        s[_YY, j] = 0.0 if on_line else yy / b
        s[_YZ, j] = 0.0 if on_line else yz / b
        s[_A, j] = a
        s[_B, j] = 0.0 if on_line else b
        s[_STATE, j] = _SAME if same else _SEARCHING
    for j in range(count):
        # hidden: the segment from E to Q meets the circle first (2-D coordinates (le, 0)
        # and (a, b)); then, as the paper's hidden map does, mirror across the tangent plane
        # where the line of sight enters the reflector: a doubly virtual vertex in front
        a, b = s[_A, j], s[_B, j]
        dx, dy = a - le, b
        qa = dx * dx + dy * dy
        qb = le * dx
        qc = le * le - r * r
        disc = qb * qb - qa * qc
        t_hit = (-qb - math.sqrt(disc)) / qa if (disc >= 0.0) & (qa > 0.0) else 2.0
        hid = (t_hit > 0.0) & (t_hit < 1.0) & (s[_STATE, j] != _SAME)
        jx, jy = le + t_hit * dx, t_hit * dy
        length = math.sqrt(jx * jx + jy * jy)
        s[_CT, j] = jx / length if hid else 1.0
        s[_ST, j] = jy / length if hid else 0.0
        s[_HIDDEN, j] = 1.0 if hid else 0.0
    for j in range(count):
        a, b = s[_A, j], s[_B, j]
        mx, my, lo, hi, u = _circle_start(le, a, b, r)
        s[_MX, j], s[_MY, j], s[_LO, j], s[_HI, j], s[_U, j] = mx, my, lo, hi, u
        search = (s[_STATE, j] != _SAME) & (s[_HIDDEN, j] == 0.0) & (b != 0.0)
        s[_STATE, j] = (s[_STATE, j] if s[_STATE, j] == _SAME else
                        (_SEARCHING if search & (mx > 0.0) else
                         (_SCALAR if search else _NORMAL)))
    for _ in range(VECTOR_STEPS):
        for j in range(count):
            st, u, lo, hi = _newton_step(s[_U, j], s[_LO, j], s[_HI, j], s[_MX, j],
                                         s[_MY, j], s[_LE, j], s[_A, j], s[_B, j], r)
            going = s[_STATE, j] == _SEARCHING
            s[_U, j] = u if going else s[_U, j]
            s[_LO, j] = lo if going else s[_LO, j]
            s[_HI, j] = hi if going else s[_HI, j]
            s[_STATE, j] = st if going else s[_STATE, j]
    for j in range(count):
        ct, st = _normal(s[_MX, j], s[_MY, j], s[_U, j])
        done = s[_STATE, j] == _DONE
        s[_CT, j] = ct if done else s[_CT, j]
        s[_ST, j] = st if done else s[_ST, j]
    # the points still searching, packed together (rows _TA.._TAIL_J) and stepped side by
    # side, the converged ones taken out after each step (up to TAIL_STEPS more steps)
    n = 0
    for j in range(count):
        if s[_STATE, j] == _SEARCHING:
            s[_TAIL_J, n] = j
            s[_TA, n], s[_TB, n], s[_TMX, n], s[_TMY, n] = s[_A, j], s[_B, j], s[_MX, j], s[_MY, j]
            s[_TLO, n], s[_THI, n], s[_TU, n] = s[_LO, j], s[_HI, j], s[_U, j]
            n += 1
    taken = VECTOR_STEPS
    while n > 0 and taken < VECTOR_STEPS + TAIL_STEPS:
        for i in range(n):
            st, u, lo, hi = _newton_step(s[_TU, i], s[_TLO, i], s[_THI, i], s[_TMX, i],
                                         s[_TMY, i], le, s[_TA, i], s[_TB, i], r)
            s[_TU, i], s[_TLO, i], s[_THI, i], s[_TSTATE, i] = u, lo, hi, st
        taken += 1
        kept = 0
        for i in range(n):
            if s[_TSTATE, i] == _DONE:
                j = int(s[_TAIL_J, i])
                s[_CT, j], s[_ST, j] = _normal(s[_TMX, i], s[_TMY, i], s[_TU, i])
                continue
            for row in range(_TA, _TAIL_J + 1):
                s[row, kept] = s[row, i]
            kept += 1
        n = kept
    for i in range(n):  # the few left after those: one at a time, from where they stand
        s[_CT, int(s[_TAIL_J, i])], s[_ST, int(s[_TAIL_J, i])] = _circle_newton(
            s[_TU, i], s[_TLO, i], s[_THI, i], s[_TMX, i], s[_TMY, i], le, s[_TA, i],
            s[_TB, i], r, 100 - taken)
    for j in range(count):
        if s[_STATE, j] == _SCALAR:
            s[_CT, j], s[_ST, j] = _circle_reflection(s[_LE, j], s[_A, j], s[_B, j], r)
    for j in range(count):
        ct, st = s[_CT, j], s[_ST, j]
        nx = ct * s[_XX, j] + st * s[_YX, j]
        ny = ct * s[_XY, j] + st * s[_YY, j]
        nz = ct * s[_XZ, j] + st * s[_YZ, j]
        # mirror Q across the tangent plane at J = C + r n (through the axis for a cylinder)
        qx, qy, qz = s[_QX, j], s[_QY, j], s[_QZ, j]
        dist = qx * nx + qy * ny + qz * nz - r
        s[_XX, j] = nx  # the normal, kept for the copy out
        s[_XY, j] = ny
        s[_XZ, j] = nz
        s[_LE, j] = dist
    for j in range(count):
        same = s[_STATE, j] == _SAME
        nx, ny, nz, dist = s[_XX, j], s[_XY, j], s[_XZ, j], s[_LE, j]
        p0, p1, p2 = points[i0 + j, 0], points[i0 + j, 1], points[i0 + j, 2]
        out[i0 + j, 0] = p0 if same else p0 - 2.0 * dist * nx
        out[i0 + j, 1] = p1 if same else p1 - 2.0 * dist * ny
        out[i0 + j, 2] = p2 if same else p2 - 2.0 * dist * nz
        hidden[i0 + j] = s[_HIDDEN, j] != 0.0
