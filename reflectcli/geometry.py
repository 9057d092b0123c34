"""Planes and reflections (world space).

A plane is (n, d) with unit normal n: points x with n.x + d = 0; n.x + d > 0 is its front.
Reflection of a point across it: x' = x - 2 (n.x + d) n.
"""

from __future__ import annotations

import numpy as np


def plane_from_points(p0, p1, p2) -> tuple[np.ndarray, float]:
    """The plane through three points, front side (p1 - p0) x (p2 - p0)."""
    p0, p1, p2 = (np.asarray(p, dtype=np.float64) for p in (p0, p1, p2))
    n = np.cross(p1 - p0, p2 - p0)
    length = np.linalg.norm(n)
    if length == 0:
        raise ValueError("degenerate plane: the points are collinear")
    n = n / length
    return n, float(-n @ p0)


def reflect_point(x, n, d: float) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    return x - 2.0 * (x @ n + d)[..., None] * n if x.ndim > 1 else x - 2.0 * (x @ n + d) * n


def reflect_vector(v, n) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v - 2.0 * (v @ n)[..., None] * n if v.ndim > 1 else v - 2.0 * (v @ n) * n


def reflection_matrix(n, d: float) -> np.ndarray:
    """The 4x4 world-space reflection across plane (n, d): [[I - 2nn^T, -2dn], [0, 1]]."""
    n = np.asarray(n, dtype=np.float64)
    m = np.eye(4)
    m[:3, :3] -= 2.0 * np.outer(n, n)
    m[:3, 3] = -2.0 * d * n
    return m


def euler_matrix(degrees) -> np.ndarray:
    """R = Rz @ Ry @ Rx: rotate about x first, then y, then z (degrees, right-handed)."""
    ax, ay, az = np.radians(np.asarray(degrees, dtype=np.float64))
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def trs_matrix(translate, rotate, scale) -> np.ndarray:
    """Object -> world: M = T @ Rz @ Ry @ Rx @ S."""
    s = np.broadcast_to(np.asarray(scale, dtype=np.float64), (3,))
    m = np.eye(4)
    m[:3, :3] = euler_matrix(rotate) @ np.diag(s)
    m[:3, 3] = translate
    return m
