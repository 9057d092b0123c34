"""Mirror geometry, planar and curved: corners and planes of planar mirrors, the world-space
triangles of every mirror shape, and the exact profiles of extrusions.

Curved reflectors built as triangle meshes: linear extrusions and spherical caps.

Both are traced by the ray tracer as triangles with interpolated (smooth) normals, so their
`mirror_mesh` is exact. The virtual-objects technique also reads an extrusion's exact
profile (`extrusion_profile`) to do its reflection computation in 2-D.

Extrusion (local space): the profile polyline lies in the xz plane and is swept along +y
from y = 0 to y = height. Its front (reflecting) side is to the LEFT of the polyline's
direction seen from +y, i.e. a segment d = (dx, dz) has the normal (dz, -dx) / |d|
(= y x d): a profile running toward -x faces +z. Each profile point's normal is the
normalised average of its adjacent segments' normals (the ends take their one segment's).
UV: u = arc length along the profile / total length, v = y / height.

Cap (local space, axis = +y, then rotated onto `axis` about the center): the points of the
sphere at polar angle theta <= angle from the pole. Normals point away from the center, or
toward it when concave; triangles are counter-clockwise seen from the reflecting side.
UV: u = longitude / (2 pi) (from the frame's x toward -z, as in `primitives`), v = 1 at the
pole falling to 0 at the rim (v = 1 - theta / angle).
"""

from __future__ import annotations

import numpy as np

from ..config.mirrors import (
    CapMirror,
    CylinderMirror,
    ExtrusionMirror,
    MeshMirror,
    QuadMirror,
    SphereMirror,
)
from ..geometry import trs_matrix
from . import primitives
from .mesh import Mesh
from .mesh_file import cached_mesh_file, resolve
from .primitives import _longitude_dirs, grid_mesh


def profile_points(profile) -> np.ndarray:
    """The profile as (N, 2) float64 with consecutive duplicate points removed."""
    p = np.asarray(profile, dtype=np.float64).reshape(-1, 2)
    if len(p) == 0:
        return p
    keep = np.ones(len(p), bool)
    keep[1:] = np.linalg.norm(np.diff(p, axis=0), axis=1) > 1e-12 * max(np.ptp(p), 1e-300)
    return p[keep]


def profile_normals(points: np.ndarray) -> np.ndarray:
    """Per-point unit normals (N, 2) of a polyline in (x, z): left of its direction seen from
    +y, averaged over the adjacent segments. Raises ValueError when the profile has fewer
    than 2 distinct points or turns straight back on itself (a zero average)."""
    p = np.asarray(points, dtype=np.float64)
    if len(p) < 2:
        raise ValueError("profile needs at least 2 distinct points")
    d = np.diff(p, axis=0)
    seg = np.stack([d[:, 1], -d[:, 0]], axis=1)
    seg /= np.linalg.norm(seg, axis=1, keepdims=True)
    n = np.zeros_like(p)
    n[:-1] += seg
    n[1:] += seg
    length = np.linalg.norm(n, axis=1, keepdims=True)
    if np.any(length < 1e-9):
        k = int(np.argmin(length[:, 0]))
        raise ValueError(f"profile turns back on itself at point {k}")
    return n / length


def extrusion_profile(m: ExtrusionMirror) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """The exact profile of an extrusion mirror, for 2-D reflection computations.

    Returns (points2d (N, 2), normals2d (N, 2), frame (4, 4), height): profile points as
    local (x, z) with consecutive duplicates removed, their unit smooth normals (front side,
    see the module doc), the local -> world matrix (the mirror's transform; local +y is the
    extrusion axis, the profile plane is local y = 0) and the local height. Normals are in
    local space: under a non-uniform scale map them with the inverse transpose of `frame`.
    """
    points = profile_points(m.profile)
    normals = profile_normals(points)
    t = m.transform
    frame = np.asarray(trs_matrix(t.translate, t.rotate, t.scale), dtype=np.float64)
    return points, normals, frame, float(m.height)


def extrusion_mesh(m: ExtrusionMirror) -> Mesh:
    """World-space triangles of an extrusion mirror: 2 (N - 1) * subdivisions triangles."""
    points, normals, frame, height = extrusion_profile(m)
    rows = int(m.subdivisions)
    y = np.linspace(0.0, height, rows + 1)
    n_pts = len(points)
    # grid (profile point k, height row j); grid_mesh's front = d/dcol x d/drow = y x d
    pos = np.zeros((n_pts, rows + 1, 3))
    pos[..., 0] = points[:, 0, None]
    pos[..., 1] = y[None, :]
    pos[..., 2] = points[:, 1, None]
    nrm = np.zeros_like(pos)
    nrm[..., 0] = normals[:, 0, None]
    nrm[..., 2] = normals[:, 1, None]
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    uu, vv = np.meshgrid(arc / arc[-1], y / height, indexing="ij")
    mesh = grid_mesh(pos, np.stack([uu, vv], axis=-1), nrm)
    return mesh.transformed(frame)


def cap_mesh(m: CapMirror) -> Mesh:
    """World-space triangles of a spherical cap mirror.

    `segments` (at least 3) facets around the axis and ceil(segments * angle / 360) rings
    (at least 1), so facets are about as wide as those of a uv sphere with `segments`; the
    ring at the pole is a fan: segments * (2 * rings - 1) triangles.
    """
    segments = max(int(m.segments), 3)
    rings = max(int(np.ceil(segments * m.angle / 360.0 - 1e-9)), 1)
    theta = np.radians(m.angle) * np.linspace(0.0, 1.0, rings + 1)
    if not m.concave:
        theta = theta[::-1]  # rows from the rim to the pole: grid_mesh's front is outward
    u = np.linspace(0.0, 1.0, segments + 1)
    radial = _longitude_dirs(u)[None, :, :]  # (1, C, 3)
    unit = np.sin(theta)[:, None, None] * radial
    unit[..., 1] = np.cos(theta)[:, None]
    uu, tt = np.meshgrid(u, theta)
    uvs = np.stack([uu, 1.0 - tt / np.radians(m.angle)], axis=-1)
    normals = -unit if m.concave else unit
    mesh = grid_mesh(m.radius * unit, uvs, normals)
    return mesh.transformed(axis_frame(m.center, m.axis))


def mirror_corners(m) -> np.ndarray:
    """A planar mirror's four corners p00, p10, p11, p01 (world)."""
    if isinstance(m, QuadMirror):
        return np.array(m.corners, float)
    n = np.array(m.normal, float)
    n /= np.linalg.norm(n)
    up = np.array(m.up, float)
    up = up - (up @ n) * n
    up /= np.linalg.norm(up)
    right = np.cross(up, n)
    c = np.array(m.center, float)
    hw, hh = m.size[0] / 2, m.size[1] / 2
    return np.array([c - hw * right - hh * up, c + hw * right - hh * up,
                     c + hw * right + hh * up, c - hw * right + hh * up])


def mirror_plane(m) -> tuple[np.ndarray, float]:
    """A planar mirror's plane (n, d), n = (p10 - p00) x (p01 - p00) normalised."""
    c = mirror_corners(m)
    n = np.cross(c[1] - c[0], c[3] - c[0])
    n /= np.linalg.norm(n)
    return n, float(-n @ c[0])


def mirror_mesh(m, source: str) -> tuple[Mesh, bool]:
    """World-space triangles of a mirror, and whether the ray tracer intersects them (mesh,
    extrusion and cap mirrors) rather than the exact shape (planar, sphere and cylinder
    mirrors, in numba)."""
    if m.planar:
        return primitives.quad(mirror_corners(m)), False
    if isinstance(m, SphereMirror):
        mesh = primitives.uv_sphere(m.radius, m.segments)
        return mesh.transformed(trs_matrix(m.center, (0, 0, 0), 1.0)), False
    if isinstance(m, CylinderMirror):
        mesh = primitives.cylinder(m.radius, m.height, m.segments, caps=False)
        return mesh.transformed(axis_frame(m.origin, m.axis)), False
    if isinstance(m, ExtrusionMirror):
        return extrusion_mesh(m), True
    if isinstance(m, CapMirror):
        return cap_mesh(m), True
    assert isinstance(m, MeshMirror)
    mesh = cached_mesh_file(resolve(source, m.path))
    t = m.transform
    mesh = mesh.transformed(trs_matrix(t.translate, t.rotate, t.scale))
    if not m.smooth:
        mesh = Mesh.flat(mesh.corners, mesh.uvs)
    return mesh, True


def axis_frame(origin, axis) -> np.ndarray:
    """A rigid transform taking local +y to `axis` and the origin to `origin`."""
    a = np.array(axis, float)
    a /= np.linalg.norm(a)
    helper = np.array([1.0, 0, 0]) if abs(a[0]) < 0.9 else np.array([0, 0, 1.0])
    x = np.cross(a, helper)
    x /= np.linalg.norm(x)
    z = np.cross(x, a)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, a, z, origin
    return m
