"""Exact virtual vertices where the reflector's geometry allows (numba, world space).

Sphere (`method = "sphere"`): the reflection point J of a scene point Q seen from the eye E
lies on the great circle through E, Q and the center C (the plane of the three), on the arc
between the directions of E and Q. With n(theta) the unit normal at angle theta from C->E
in that plane, the law of reflection says the unit vectors from J to E and to Q are mirror
images about n: f(theta) = n x u_E + n x u_Q = 0 (2-D cross products). f > 0 at theta = 0
and < 0 at the direction of Q, so bisection finds J (the thesis the paper defers to is not
at hand; this is the numerical solution the issue suggests). Q' is Q mirrored across the
tangent plane at J. A hidden Q (the line of sight to it enters the reflector first) is
mirrored across the tangent plane where the line of sight enters, like the paper's hidden
map: its doubly virtual vertex lies in front of the reflector and only closes polygons.

Cylinder (`method = "extrusion"`): the normals lie in planes perpendicular to the axis, so
the law of reflection holds for the projections onto such a plane: the same circle problem
in the cross-section (a binary search over the section's angle, the paper's 2-D search for
linear extrusions), and Q' is Q mirrored across the plane through the axis direction and J.
Points inside the reflector keep Q' = Q.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(cache=True)
def _circle_reflection(ex, ey, qx, qy, r):
    """Angle theta (from +x) of the reflection point on a circle of radius r at the origin
    for E = (ex, ey) on the +x axis (ey = 0) and Q = (qx, qy) with qy >= 0."""
    phi = math.atan2(qy, qx)
    lo, hi = 0.0, phi
    for _ in range(44):  # 2^-44 of the arc: far below a texel
        mid = 0.5 * (lo + hi)
        nx, ny = math.cos(mid), math.sin(mid)
        jx, jy = r * nx, r * ny
        ux, uy = ex - jx, ey - jy
        inv = 1.0 / math.sqrt(ux * ux + uy * uy)
        ux, uy = ux * inv, uy * inv
        vx, vy = qx - jx, qy - jy
        inv = 1.0 / max(math.sqrt(vx * vx + vy * vy), 1e-300)
        vx, vy = vx * inv, vy * inv
        f = (nx * uy - ny * ux) + (nx * vy - ny * vx)
        if f > 0.0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


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
        theta = math.atan2(jy, jx)
    elif b == 0.0:
        theta = 0.0
    else:
        theta = _circle_reflection(le, 0.0, a, b, r)
    ct, st = math.cos(theta), math.sin(theta)
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
