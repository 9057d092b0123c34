"""Exact virtual vertices where the reflector's geometry allows (numba, world space).

Sphere (`method = "sphere"`): the reflection point J of a scene point Q seen from the eye E
lies on the great circle through E, Q and the center C (the plane of the three), on the arc
between the directions of E and Q. With n(theta) the unit normal at angle theta from C->E
in that plane, the law of reflection says the unit vectors from J to E and to Q are mirror
images about n: f(theta) = n x u_E + n x u_Q = 0 (2-D cross products). f > 0 at theta = 0
and < 0 at the direction of Q, so a bracketing root search (regula falsi) finds J (the
thesis the paper defers to is not at hand; this is the numerical solution the issue
suggests). Q' is Q mirrored across the
tangent plane at J. A hidden Q (the line of sight to it enters the reflector first) is
mirrored across the tangent plane where the line of sight enters, like the paper's hidden
map: its doubly virtual vertex lies in front of the reflector and only closes polygons.

Cylinder (`method = "extrusion"`): the normals lie in planes perpendicular to the axis, so
the law of reflection holds for the projections onto such a plane: the same circle problem
in the cross-section (a binary search over the section's angle, the paper's 2-D search for
linear extrusions), and Q' is Q mirrored across the plane through the axis direction and J.
Points inside the reflector keep Q' = Q.

General linear extrusion (`method = "extrusion"` on an extrusion mirror, the TV of Fig. 17):
the same 2-D problem against the profile polyline with normals interpolated along it: the
sign of f at the profile's vertices finds the segment holding the reflection point (the
coarse level of the paper's binary-search hierarchy), bisection finds it within. Where no
segment brackets a root (the point's reflection lies off the profile's ends), the nearer
end is used: a doubly virtual vertex. Works in the extrusion's local frame, so the transform
must be a similarity (uniform scale).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(cache=True, inline="always")
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


@njit(cache=True)
def _circle_reflection(ex, ey, qx, qy, r):
    """Unit normal (cos theta, sin theta) at the reflection point on a circle of radius r at
    the origin for E = (ex, ey) on the +x axis (ey = 0) and Q = (qx, qy) with qy >= 0.

    The root of f on [0, phi_Q] is bracketed. Newton's method, kept inside the shrinking
    bracket (bisection whenever a step would leave it), on u = tan(theta - phi_Q / 2): the
    normal n(u) = (m + u m_perp) / sqrt(1 + u^2) around the bisector m of the bracket needs
    no trigonometry (d theta / du = 1 / (1 + u^2)). It starts from the blend of the bracket's
    end normals in the ratio of the two points' heights above the circle (right when they
    are equal, and at either end as one of them reaches the circle). About 4 evaluations of
    f where regula falsi took about 12, to about 1e-13 rad."""
    lq = math.sqrt(qx * qx + qy * qy)
    cx, cy = qx / lq, qy / lq  # the normal at phi_Q (the bracket's far end)
    # the signs at the ends need no evaluation: at theta = 0, n x u_E = 0 and n x u_Q =
    # qy / |Q - J| > 0; at phi_Q, n x u_Q = 0 and n x u_E = -cy ex / |E - J| < 0
    if not (qy > 0.0 and ex > 0.0):
        return 1.0, 0.0
    # the bisector m of [0, phi_Q] by the half-angle formulas (phi_Q in [0, pi])
    mx = math.sqrt(max(0.5 * (1.0 + cx), 0.0))
    my = math.sqrt(max(0.5 * (1.0 - cx), 0.0))
    px, py = -my, mx  # m_perp
    lo, hi = -np.inf, np.inf  # the bracket in u: +-tan(phi_Q / 2)
    if mx > 0.0:
        hi = my / mx
        lo = -hi
    height_e = max(math.sqrt(ex * ex + ey * ey) - r, 0.0)
    height_q = max(lq - r, 0.0)
    w = 0.5 if height_e + height_q <= 0.0 else height_e / (height_e + height_q)
    gx, gy = (1.0 - w) + w * cx, w * cy  # the blend of the ends' normals (unnormalized)
    along = gx * mx + gy * my
    u = (gx * px + gy * py) / along if along > 0.0 else 0.0
    if not lo < u < hi:
        u = 0.0
    nx, ny = mx, my
    for _ in range(100):
        inv = 1.0 / math.sqrt(1.0 + u * u)
        nx, ny = (mx + u * px) * inv, (my + u * py) * inv
        f, slope = _circle_law(nx, ny, ex, ey, qx, qy, r)
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
        # a Newton step below 1e-8 rad leaves an error of order its square: done
        if abs(nxt - u) * inv * inv < 1e-8 or (hi - lo) * inv * inv < 1e-13:
            inv = 1.0 / math.sqrt(1.0 + nxt * nxt)
            return (mx + nxt * px) * inv, (my + nxt * py) * inv
        u = nxt
    return nx, ny


@njit(cache=True)
def _mirror_on_circle(e, q, c, r, axis, use_axis):
    """(Q', hidden) for a sphere (use_axis False) or a cylinder with unit `axis`."""
    ex, ey, ez = e[0] - c[0], e[1] - c[1], e[2] - c[2]
    qx, qy, qz = q[0] - c[0], q[1] - c[1], q[2] - c[2]
    if use_axis:  # project onto the cross-section plane
        de = ex * axis[0] + ey * axis[1] + ez * axis[2]
        dq = qx * axis[0] + qy * axis[1] + qz * axis[2]
        ex, ey, ez = ex - de * axis[0], ey - de * axis[1], ez - de * axis[2]
        qx, qy, qz = qx - dq * axis[0], qy - dq * axis[1], qz - dq * axis[2]
    le = math.sqrt(ex * ex + ey * ey + ez * ez)
    lq = math.sqrt(qx * qx + qy * qy + qz * qz)
    if lq <= r or le <= r:
        return q[0], q[1], q[2], False
    xx, xy, xz = ex / le, ey / le, ez / le  # 2-D x axis: toward the eye
    a = qx * xx + qy * xy + qz * xz
    yx, yy, yz = qx - a * xx, qy - a * xy, qz - a * xz
    b = math.sqrt(yx * yx + yy * yy + yz * yz)
    if b < 1e-12 * lq:  # Q on the line through C and E
        yx, yy, yz = 0.0, 0.0, 0.0
        b = 0.0
    else:
        yx, yy, yz = yx / b, yy / b, yz / b
    # hidden: the segment from E to Q meets the circle first (2-D coordinates (le, 0) and
    # (a, b)); then, as the paper's hidden map does, mirror across the tangent plane where
    # the line of sight enters the reflector: a doubly virtual vertex in front of it
    dx, dy = a - le, b
    qa = dx * dx + dy * dy
    qb = le * dx
    qc = le * le - r * r
    disc = qb * qb - qa * qc
    t_hit = (-qb - math.sqrt(disc)) / qa if disc >= 0.0 and qa > 0.0 else 2.0
    hidden = 0.0 < t_hit < 1.0
    if hidden:
        jx, jy = le + t_hit * dx, t_hit * dy
        length = math.sqrt(jx * jx + jy * jy)
        ct, st = jx / length, jy / length
    elif b == 0.0:
        ct, st = 1.0, 0.0
    else:
        ct, st = _circle_reflection(le, 0.0, a, b, r)
    nx, ny, nz = ct * xx + st * yx, ct * xy + st * yy, ct * xz + st * yz
    # mirror Q across the tangent plane at J = C + r n (through the axis for a cylinder)
    dist = qx * nx + qy * ny + qz * nz - r
    return q[0] - 2.0 * dist * nx, q[1] - 2.0 * dist * ny, q[2] - 2.0 * dist * nz, hidden


def sphere_virtual_vertices(points: np.ndarray, eye: np.ndarray, center: np.ndarray,
                            radius: float) -> tuple[np.ndarray, np.ndarray]:
    """(virtual points (N, 3), hidden (N,) bool) for a sphere mirror."""
    out = np.empty(points.shape, np.float64)
    hidden = np.empty(points.shape[0], np.bool_)
    _many(np.ascontiguousarray(points, np.float64), np.asarray(eye, np.float64),
          np.asarray(center, np.float64), float(radius), np.zeros(3), False, out, hidden)
    return out, hidden


def cylinder_virtual_vertices(points: np.ndarray, eye: np.ndarray, origin: np.ndarray,
                              axis: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """(virtual points (N, 3), hidden (N,) bool) for a cylinder mirror."""
    out = np.empty(points.shape, np.float64)
    hidden = np.empty(points.shape[0], np.bool_)
    a = np.asarray(axis, np.float64)
    _many(np.ascontiguousarray(points, np.float64), np.asarray(eye, np.float64),
          np.asarray(origin, np.float64), float(radius), a / np.linalg.norm(a), True, out,
          hidden)
    return out, hidden


@njit(cache=True, parallel=True)
def _many(points, eye, center, radius, axis, use_axis, out, hidden):
    for i in prange(points.shape[0]):
        x, y, z, h = _mirror_on_circle(eye, points[i], center, radius, axis, use_axis)
        out[i, 0] = x
        out[i, 1] = y
        out[i, 2] = z
        hidden[i] = h


def profile_virtual_vertices(points: np.ndarray, eye: np.ndarray, profile: np.ndarray,
                             normals: np.ndarray, world_from_local: np.ndarray):
    """(virtual points (N, 3), hidden (N,) bool) for a linear extrusion of `profile`
    (local x, z); points, eye and the result in world space."""
    local_from_world = np.linalg.inv(world_from_local)
    local = np.ascontiguousarray(
        points @ local_from_world[:3, :3].T + local_from_world[:3, 3], np.float64)
    e = local_from_world[:3, :3] @ np.asarray(eye, np.float64) + local_from_world[:3, 3]
    out = np.empty(points.shape, np.float64)
    hidden = np.empty(points.shape[0], np.bool_)
    _profile_many(local, e, np.ascontiguousarray(profile, np.float64),
                  np.ascontiguousarray(normals, np.float64), out, hidden)
    return out @ world_from_local[:3, :3].T + world_from_local[:3, 3], hidden


@njit(cache=True)
def _profile_at(profile, normals, t):
    """Point and unit normal at parameter t in [0, N - 1] along the polyline."""
    last = profile.shape[0] - 1
    s = min(int(math.floor(t)), last - 1)
    a = t - s
    jx = (1 - a) * profile[s, 0] + a * profile[s + 1, 0]
    jz = (1 - a) * profile[s, 1] + a * profile[s + 1, 1]
    nx = (1 - a) * normals[s, 0] + a * normals[s + 1, 0]
    nz = (1 - a) * normals[s, 1] + a * normals[s + 1, 1]
    inv = 1.0 / math.sqrt(nx * nx + nz * nz)
    return jx, jz, nx * inv, nz * inv


@njit(cache=True)
def _law(profile, normals, t, ex, ez, qx, qz):
    """f(t) = n x u_E + n x u_Q (2-D): zero at a reflection point."""
    jx, jz, nx, nz = _profile_at(profile, normals, t)
    ux, uz = ex - jx, ez - jz
    inv = 1.0 / max(math.sqrt(ux * ux + uz * uz), 1e-300)
    vx, vz = qx - jx, qz - jz
    inv2 = 1.0 / max(math.sqrt(vx * vx + vz * vz), 1e-300)
    return (nx * uz * inv - nz * ux * inv) + (nx * vz * inv2 - nz * vx * inv2)


@njit(cache=True, parallel=True)
def _profile_many(points, e, profile, normals, out, hidden):
    for i in prange(points.shape[0]):
        x, y, z, h = _profile_one(points[i, 0], points[i, 1], points[i, 2], e, profile, normals)
        out[i, 0] = x
        out[i, 1] = y
        out[i, 2] = z
        hidden[i] = h


@njit(cache=True)
def _profile_one(qx, qy, qz, e, profile, normals):
    """(Q' x, y, z, hidden) in the extrusion's local frame (y along the extrusion)."""
    last = profile.shape[0] - 1
    # hidden: the line of sight (2-D) crosses the profile before reaching Q
    t_hit = 2.0
    param = -1.0
    for s in range(last):
        ax, az = profile[s, 0], profile[s, 1]
        sx, sz = profile[s + 1, 0] - ax, profile[s + 1, 1] - az
        dx, dz = qx - e[0], qz - e[2]
        den = dx * sz - dz * sx
        if den == 0.0:
            continue
        t = ((ax - e[0]) * sz - (az - e[2]) * sx) / den
        u = ((ax - e[0]) * dz - (az - e[2]) * dx) / den
        if 0.0 < t < t_hit and 0.0 <= u <= 1.0:
            t_hit = t
            param = s + u
    hidden = param >= 0.0
    if not hidden:
        # coarse level: the segment whose ends bracket a sign change of f
        lo = -1.0
        hi = -1.0
        f_prev = _law(profile, normals, 0.0, e[0], e[2], qx, qz)
        best = 0.0
        best_f = abs(f_prev)
        for s in range(1, last + 1):
            f = _law(profile, normals, float(s), e[0], e[2], qx, qz)
            if abs(f) < best_f:
                best = float(s)
                best_f = abs(f)
            if (f_prev > 0.0) != (f > 0.0):
                lo = float(s - 1)
                hi = float(s)
                break
            f_prev = f
        if lo < 0.0:
            param = best
        else:
            f_lo = _law(profile, normals, lo, e[0], e[2], qx, qz)
            for _ in range(40):
                mid = 0.5 * (lo + hi)
                f_mid = _law(profile, normals, mid, e[0], e[2], qx, qz)
                if (f_mid > 0.0) == (f_lo > 0.0):
                    lo = mid
                    f_lo = f_mid
                else:
                    hi = mid
            param = 0.5 * (lo + hi)
    jx, jz, nx, nz = _profile_at(profile, normals, param)
    dist = (qx - jx) * nx + (qz - jz) * nz
    return qx - 2.0 * dist * nx, qy, qz - 2.0 * dist * nz, hidden
