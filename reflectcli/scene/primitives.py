"""Analytic primitives, each built straight into a `Mesh` in its own object space.

Shared conventions, so textures line up across shapes:
- y is up; triangles are counter-clockwise seen from the front (outside, or inside for `room`).
- Angles around the y axis ("longitude") start at +x and turn toward -z, which is the
  direction that keeps du x dv pointing outward when v runs up.
- Curved surfaces carry analytic (smooth) normals; planar faces carry flat ones.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from reflectcli.scene.mesh import Mesh

ROOM_FACES = ("floor", "ceiling", "north", "south", "west", "east")

_DEFAULT_QUAD_UV = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def _unit(v: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(length > 0, length, 1.0)


def grid_mesh(positions: np.ndarray, uvs: np.ndarray, normals: np.ndarray) -> Mesh:
    """Triangulate a (R+1, C+1) vertex grid: two triangles per cell, front = d/dcol x d/drow.

    Grids are how every parametric surface here is sampled; keeping one triangulation rule
    means one winding rule. Cell (i, j) becomes (p00, p10, p11) and (p00, p11, p01) with
    p00 = [i, j], p10 = [i, j+1], p11 = [i+1, j+1], p01 = [i+1, j]. Leading batch axes are
    allowed (e.g. one grid per patch); zero-area triangles (poles) are dropped.
    """
    p = np.asarray(positions, dtype=np.float64)
    t = np.asarray(uvs, dtype=np.float64)
    n = np.asarray(normals, dtype=np.float64)

    def tris(a: np.ndarray) -> np.ndarray:
        a00, a10 = a[..., :-1, :-1, :], a[..., :-1, 1:, :]
        a11, a01 = a[..., 1:, 1:, :], a[..., 1:, :-1, :]
        first = np.stack([a00, a10, a11], axis=-2)
        second = np.stack([a00, a11, a01], axis=-2)
        both = np.stack([first, second], axis=-3)  # (..., R, C, 2, 3, k)
        return both.reshape(-1, 3, a.shape[-1])

    return Mesh(tris(p), tris(t), tris(n)).without_degenerate(0.0)


def quad(corners: Sequence[Sequence[float]] | np.ndarray, uv: np.ndarray | None = None) -> Mesh:
    """Two flat triangles from corners p00, p10, p11, p01; front = (p10 - p00) x (p01 - p00).

    UV: one uv per corner in the same order, default (0,0), (1,0), (1,1), (0,1), i.e. u runs
    p00 -> p10 and v runs p00 -> p01. Local frame: whatever frame the corners are in.
    """
    c = np.asarray(corners, dtype=np.float64).reshape(4, 3)
    t = _DEFAULT_QUAD_UV if uv is None else np.asarray(uv, dtype=np.float64).reshape(4, 2)
    idx = np.array([[0, 1, 2], [0, 2, 3]])
    normal = _unit(np.cross(c[1] - c[0], c[3] - c[0]))
    return Mesh(c[idx], t[idx].copy(), np.broadcast_to(normal, (2, 3, 3)).copy())


def _rect(origin: np.ndarray, eu: np.ndarray, ev: np.ndarray) -> Mesh:
    """A quad whose uv (0,0)->(1,1) spans origin -> origin + eu + ev; front = eu x ev."""
    return quad([origin, origin + eu, origin + eu + ev, origin + ev])


def _box_faces(lo: np.ndarray, hi: np.ndarray) -> dict[str, tuple]:
    """Outward-facing (origin, eu, ev) per face; `room` reuses them mirrored in u."""
    dx, dy, dz = hi - lo
    x, y, z = np.eye(3)
    return {
        # walls seen from outside: u to the viewer's right, v up
        "south": (np.array([lo[0], lo[1], hi[2]]), dx * x, dy * y),  # +z
        "north": (np.array([hi[0], lo[1], lo[2]]), -dx * x, dy * y),  # -z
        "east": (np.array([hi[0], lo[1], hi[2]]), -dz * z, dy * y),  # +x
        "west": (np.array([lo[0], lo[1], lo[2]]), dz * z, dy * y),  # -x
        # top seen from above: u = +x, v = -z; bottom seen from below: u = +x, v = +z
        "ceiling": (np.array([lo[0], hi[1], hi[2]]), dx * x, -dz * z),  # +y
        "floor": (np.array([lo[0], lo[1], lo[2]]), dx * x, dz * z),  # -y
    }


def box(min: Sequence[float], max: Sequence[float]) -> Mesh:
    """Axis-aligned box, 12 triangles, faces outward, flat normals.

    UV: every face spans [0,1]^2. Side faces seen from outside: u to the viewer's right, v up
    (+y). Top (+y) seen from above: u = +x, v = -z. Bottom (-y) seen from below: u = +x,
    v = +z. Local frame: the given world-aligned min/max corners.
    """
    lo, hi = np.asarray(min, dtype=np.float64), np.asarray(max, dtype=np.float64)
    faces = _box_faces(lo, hi)
    mesh = Mesh.concatenate([_rect(*faces[name]) for name in ROOM_FACES])
    return mesh.closed() if np.all(lo < hi) else mesh


def room(
    min: Sequence[float],
    max: Sequence[float],
    faces: Iterable[str] | None = None,
) -> Mesh:
    """A box seen from inside: faces point inward so the camera and mirrors live within it.

    UV (each face spans [0,1]^2): walls seen from inside the room have u to the viewer's
    right and v up (+y); floor u = +x, v = -z; ceiling u = +x, v = +z. `faces` picks a subset
    of "floor", "ceiling", "north" (-z wall), "south" (+z), "west" (-x), "east" (+x); the
    order of the output follows ROOM_FACES. Local frame: world-aligned min/max corners.
    """
    lo, hi = np.asarray(min, dtype=np.float64), np.asarray(max, dtype=np.float64)
    wanted = ROOM_FACES if faces is None else tuple(faces)
    unknown = set(wanted) - set(ROOM_FACES)
    if unknown:
        raise ValueError(f"unknown room faces {sorted(unknown)}; expected some of {ROOM_FACES}")
    outward = _box_faces(lo, hi)
    meshes = []
    for name in ROOM_FACES:
        if name not in wanted:
            continue
        origin, eu, ev = outward[name]
        if name in ("floor", "ceiling"):
            # flip v: floor becomes u=+x, v=-z (front +y); ceiling u=+x, v=+z (front -y)
            meshes.append(_rect(origin + ev, eu, -ev))
        else:
            # flip u: the viewer's right seen from inside is the left seen from outside
            meshes.append(_rect(origin + eu, -eu, ev))
    return Mesh.concatenate(meshes)


def _longitude_dirs(u: np.ndarray) -> np.ndarray:
    """Unit radial directions in the xz plane for u = angle/(2pi), angle from +x toward -z."""
    a = 2.0 * np.pi * u
    return np.stack([np.cos(a), np.zeros_like(a), -np.sin(a)], axis=-1)


def uv_sphere(radius: float, segments: int) -> Mesh:
    """Latitude/longitude sphere centred at the origin, `segments` around, segments//2 rings.

    UV: u = longitude/(2pi), longitude measured from +x toward -z (u=0.25 at -z); v = latitude
    mapped south pole (y=-r) 0 -> north pole (y=+r) 1. The seam column is duplicated (u=0 and
    u=1) so no triangle straddles the wrap; pole corners take the mid-u of their triangle.
    Normals are analytic (position / radius). Pole triangles are single, not degenerate quads.
    """
    segments = max(int(segments), 3)
    rings = max(segments // 2, 2)
    u = np.linspace(0.0, 1.0, segments + 1)
    v = np.linspace(0.0, 1.0, rings + 1)
    lat = np.pi * (v - 0.5)
    ring_r = np.cos(lat)
    ring_r[[0, -1]] = 0.0  # exact poles so their cells collapse to single triangles
    ring_y = np.sin(lat)
    ring_y[[0, -1]] = [-1.0, 1.0]
    normals = ring_r[:, None, None] * _longitude_dirs(u)[None, :, :]
    normals[..., 1] = ring_y[:, None]
    uu, vv = np.meshgrid(u, v)
    half = 0.5 / segments
    uu[0] += half
    uu[-1] -= half
    uvs = np.stack([np.clip(uu, 0.0, 1.0), vv], axis=-1)
    return grid_mesh(radius * normals, uvs, normals).closed()


def ico_sphere(radius: float, subdivisions: int) -> Mesh:
    """Geodesic sphere (trimesh icosphere): evenly sized triangles, no pole pinching.

    UV: same spherical mapping as `uv_sphere` (u = longitude from +x toward -z over 2pi,
    v = 0 south pole -> 1 north pole), computed per corner. Triangles crossing the seam get
    their small-u corners shifted by +1, so u may reach slightly above 1 (use a wrapping
    sampler); pole corners take the mean u of the other corners. Normals are analytic.
    """
    import trimesh

    ico = trimesh.creation.icosphere(subdivisions=int(subdivisions), radius=1.0)
    unit = _unit(np.asarray(ico.vertices, dtype=np.float64))[np.asarray(ico.faces)]
    u = (np.arctan2(-unit[..., 2], unit[..., 0]) / (2.0 * np.pi)) % 1.0
    v = 0.5 + np.arcsin(np.clip(unit[..., 1], -1.0, 1.0)) / np.pi
    pole = np.hypot(unit[..., 0], unit[..., 2]) < 1e-9
    u = np.where(pole, np.nan, u)
    wraps = (np.nanmax(u, axis=1) - np.nanmin(u, axis=1)) > 0.5
    u = np.where(wraps[:, None] & (u < 0.5), u + 1.0, u)
    u = np.where(pole, np.nanmean(u, axis=1, keepdims=True), u)
    return Mesh(radius * unit, np.stack([u, v], axis=-1), unit.copy()).closed()


def _disk(radius: float, segments: int, y: float, up: bool) -> Mesh:
    """Flat triangle-fan cap at height y; up=True faces +y.

    UV: planar, seen from the side it faces: up -> u = +x, v = -z; down -> u = +x, v = +z,
    both mapping [-r, r] to [0, 1].
    """
    u = np.linspace(0.0, 1.0, segments + 1)
    rim = radius * _longitude_dirs(u)
    rim[:, 1] = y
    center = np.broadcast_to([0.0, y, 0.0], (segments, 3))
    a, b = rim[:-1], rim[1:]
    corners = np.stack([center, a, b] if up else [center, b, a], axis=1)
    sign = -1.0 if up else 1.0
    uvs = np.stack(
        [(corners[..., 0] / radius + 1) / 2, (sign * corners[..., 2] / radius + 1) / 2], -1
    )
    return Mesh.flat(corners, uvs)


def cylinder(radius: float, height: float, segments: int, caps: bool = True) -> Mesh:
    """Cylinder on the +y axis from y=0 to y=height; `segments` facets around.

    UV: sides u = angle/(2pi) (angle from +x toward -z), v = y/height, smooth radial normals;
    caps (when `caps`) are flat with planar uv: top u = +x, v = -z, bottom u = +x, v = +z,
    each mapping [-radius, radius] to [0, 1].
    """
    segments = max(int(segments), 3)
    u = np.linspace(0.0, 1.0, segments + 1)
    v = np.array([0.0, 1.0])
    radial = np.broadcast_to(_longitude_dirs(u), (2, segments + 1, 3))
    positions = radius * radial.copy()
    positions[..., 1] = height * v[:, None]
    uu, vv = np.meshgrid(u, v)
    side = grid_mesh(positions, np.stack([uu, vv], -1), radial)
    if not caps:
        return side
    return Mesh.concatenate(
        [side, _disk(radius, segments, height, up=True), _disk(radius, segments, 0.0, up=False)]
    ).closed()


def cone(radius: float, height: float, segments: int) -> Mesh:
    """Cone with its base disk on y=0 and apex at (0, height, 0).

    UV: sides u = angle/(2pi) (from +x toward -z), v = y/height (apex corners use their
    triangle's mid-angle); base cap flat, planar u = +x, v = +z over [-r, r] -> [0, 1].
    Side normals are the analytic slant normals at each corner's angle (smooth around).
    """
    segments = max(int(segments), 3)
    u = np.linspace(0.0, 1.0, segments + 1)
    mid = 0.5 * (u[:-1] + u[1:])
    rim = radius * _longitude_dirs(u)
    apex = np.broadcast_to([0.0, height, 0.0], (segments, 3))
    corners = np.stack([rim[:-1], rim[1:], apex], axis=1)

    def slant(t: np.ndarray) -> np.ndarray:
        n = height * _longitude_dirs(t)
        n[..., 1] = radius
        return _unit(n)

    normals = np.stack([slant(u[:-1]), slant(u[1:]), slant(mid)], axis=1)
    uvs = np.stack(
        [
            np.stack([u[:-1], np.zeros(segments)], -1),
            np.stack([u[1:], np.zeros(segments)], -1),
            np.stack([mid, np.ones(segments)], -1),
        ],
        axis=1,
    )
    return Mesh.concatenate([Mesh(corners, uvs, normals),
                             _disk(radius, segments, 0.0, up=False)]).closed()


def pyramid(size: float, height: float) -> Mesh:
    """Square pyramid: base of side `size` centred on the origin at y=0, apex (0, height, 0).

    UV: each side triangle, seen from outside, has its base-left corner (0,0), base-right
    (1,0) and apex (0.5,1); the base (two triangles, facing -y) seen from below has
    u = +x, v = +z spanning [0,1]. Flat normals. Rotate 180 degrees for the inverted pyramid.
    """
    h = 0.5 * size
    apex = np.array([0.0, height, 0.0])
    # base corners counter-clockwise seen from above (+y): the outside-left-to-right order
    ring = np.array([[-h, 0, h], [h, 0, h], [h, 0, -h], [-h, 0, -h]], dtype=np.float64)
    sides = np.stack([ring, np.roll(ring, -1, axis=0), np.broadcast_to(apex, (4, 3))], axis=1)
    side_uv = np.broadcast_to(np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]]), (4, 3, 2))
    base_corners = np.array([[-h, 0, -h], [h, 0, -h], [h, 0, h], [-h, 0, h]], dtype=np.float64)
    base = quad(base_corners)
    return Mesh.concatenate([Mesh.flat(sides, side_uv.copy()), base]).closed()


def torus(
    major_radius: float, minor_radius: float, major_segments: int, minor_segments: int
) -> Mesh:
    """Torus lying in the xz plane around the y axis, centred at the origin.

    UV: u = major angle/(2pi) (from +x toward -z), v = minor angle/(2pi) with v=0 on the
    outer equator and v=0.25 on top (+y); seams duplicated so no triangle wraps.
    Normals are analytic (from the tube centre to the point).
    """
    major_segments, minor_segments = max(int(major_segments), 3), max(int(minor_segments), 3)
    u = np.linspace(0.0, 1.0, major_segments + 1)
    v = np.linspace(0.0, 1.0, minor_segments + 1)
    radial = _longitude_dirs(u)[None, :, :]  # (1, U, 3)
    phi = 2.0 * np.pi * v[:, None, None]  # (V, 1, 1)
    normals = np.cos(phi) * radial + np.sin(phi) * np.array([0.0, 1.0, 0.0])
    positions = major_radius * radial + minor_radius * normals
    uu, vv = np.meshgrid(u, v)
    mesh = grid_mesh(positions, np.stack([uu, vv], -1), normals)
    return mesh.closed() if minor_radius < major_radius else mesh  # a spindle torus folds
