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


def transform_plane(plane, matrix) -> np.ndarray:
    """The plane (4,) of points x, re-expressed for points y = matrix @ x: M^-T @ plane."""
    return np.linalg.inv(np.asarray(matrix, dtype=np.float64)).T @ np.asarray(plane, float)


def oblique_projection(projection, plane_eye) -> np.ndarray:
    """Lengyel's oblique near plane: replace the near plane of an OpenGL projection by
    `plane_eye` (a, b, c, d in eye space; the camera must lie on its negative side, and points
    with a x + b y + c z + d >= 0 are kept).

    Only the third row changes, so clip-space x, y and w (hence the image and eye-space
    depth) are untouched; points on the plane get NDC z = -1 and depth order along each view
    ray is kept in front of it. The far plane becomes the plane through the far corner of the
    old frustum opposite the new near plane: it tilts with the mirror, and an NDC-z depth
    buffer loses precision as the mirror plane turns away from the view axis (the NDC z range
    spent on the visible part shrinks). Our z-buffer holds eye-space depth, so the only cost
    here is that clipping must not use the tilted far plane; see `far_plane_clip`.
    """
    p = np.array(projection, dtype=np.float64)
    c = np.asarray(plane_eye, dtype=np.float64)
    q = np.linalg.inv(p) @ np.array([np.sign(c[0]), np.sign(c[1]), 1.0, 1.0])
    scaled = c * (2.0 / (c @ q))
    p[2] = scaled - p[3]
    return p


def far_plane_clip(projection, far: float) -> np.ndarray:
    """The eye-space far plane z_eye >= -far as a clip-space plane of `projection`."""
    return transform_plane(np.array([0.0, 0.0, 1.0, far]), projection)
