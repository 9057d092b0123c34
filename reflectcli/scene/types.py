"""The built scene: flat float32/int32 arrays that numba kernels take directly.

Surface ids number objects first (0 .. n_objects-1), then mirrors
(n_objects .. n_objects+n_mirrors-1); -1 is the background. Triangle arrays are world space.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

# material kinds (mat_i[:, 0])
SOLID, CHECKER, TEXTURE = 0, 1, 2
# mirror kinds
PLANAR, SPHERE, CYLINDER, MESH = 0, 1, 2, 3
MIRROR_PARAMS = 16
# Column offsets into a row of Mirrors.params. Python code reads rows through the named
# accessors of Mirrors (plane, corners, sphere, cylinder); numba kernels, which cannot call
# them, index a row with these (`p[SPHERE_RADIUS]`, `p[CYLINDER_AXIS + 1]`).
PLANE_NORMAL, PLANE_D = 0, 3  # planar: unit normal xyz, d (n . x + d = 0 on the plane)
PLANE_P00, PLANE_P10, PLANE_P11, PLANE_P01 = 4, 7, 10, 13  # planar: corners, xyz each
SPHERE_CENTER, SPHERE_RADIUS = 0, 3  # sphere: center xyz, radius
CYLINDER_ORIGIN, CYLINDER_AXIS, CYLINDER_RADIUS, CYLINDER_HEIGHT = 0, 3, 6, 7  # axis unit

# shading modes
UNLIT, LAMBERT = 0, 1
# light kinds
POINT, DIRECTIONAL = 0, 1

# A mirror wins a depth tie against any other surface: its depth is scaled by this factor
# before the comparison, in the rasterizer and in the ray tracer alike (a mirror flush with
# its wall shows no z-fighting).
MIRROR_TIE = 1.0 - 1e-4


@dataclass(frozen=True)
class Materials:
    """mat_i: (M, 5) kind, texel offset, texture width, height, bilinear flag.
    mat_f: (M, 8) color0 rgb, color1 rgb, scale u, scale v. texels: (N, 3) linear RGB."""

    names: list[str]
    mat_i: np.ndarray
    mat_f: np.ndarray
    texels: np.ndarray


@dataclass(frozen=True)
class Lights:
    """light_f: (L, 7) kind, position-or-direction xyz (direction unit, the way light travels),
    intensity * color rgb."""

    light_f: np.ndarray


@dataclass(frozen=True)
class Mirrors:
    """Per mirror: kind, reflectance rgb, base rgb and shape parameters (world space).

    params (float64) columns (offsets named PLANE_*, SPHERE_*, CYLINDER_* above): planar: n
    xyz, d, then corners p00 p10 p11 p01 (xyz each); sphere: center xyz, radius; cylinder:
    origin xyz, axis xyz (unit), radius, height; mesh: unused (its triangles are in
    Geometry.mirror_tris).
    """

    names: list[str]
    kind: np.ndarray  # (M,) int32
    reflectance: np.ndarray  # (M, 3) float32
    base: np.ndarray  # (M, 3) float32
    params: np.ndarray  # (M, MIRROR_PARAMS) float64

    @property
    def count(self) -> int:
        return len(self.names)

    # named views of `params` (read them through these, not by column)
    def plane(self, k: int) -> tuple[np.ndarray, float]:
        """Planar mirror k's plane (n, d): unit n (float64 copy), n.x + d = 0 on it."""
        n = self.params[k, PLANE_NORMAL:PLANE_NORMAL + 3]
        return n.astype(np.float64), float(self.params[k, PLANE_D])

    def corners(self, k: int) -> np.ndarray:
        """Planar mirror k's corners p00, p10, p11, p01 (4, 3), world."""
        return self.params[k, PLANE_P00:PLANE_P01 + 3].reshape(4, 3)

    def sphere(self, k: int) -> tuple[np.ndarray, float]:
        """Sphere mirror k's (center (3,), radius)."""
        p = self.params[k]
        return p[SPHERE_CENTER:SPHERE_CENTER + 3], p[SPHERE_RADIUS]

    def cylinder(self, k: int) -> tuple[np.ndarray, np.ndarray, float, float]:
        """Cylinder mirror k's (origin (3,), unit axis (3,), radius, height)."""
        p = self.params[k]
        return (p[CYLINDER_ORIGIN:CYLINDER_ORIGIN + 3], p[CYLINDER_AXIS:CYLINDER_AXIS + 3],
                p[CYLINDER_RADIUS], p[CYLINDER_HEIGHT])

    @staticmethod
    def planar_row(n, d: float, corners) -> np.ndarray:
        row = np.zeros(MIRROR_PARAMS)
        row[PLANE_NORMAL:PLANE_NORMAL + 3], row[PLANE_D] = n, d
        row[PLANE_P00:PLANE_P01 + 3] = np.asarray(corners).reshape(-1)
        return row

    @staticmethod
    def sphere_row(center, radius: float) -> np.ndarray:
        row = np.zeros(MIRROR_PARAMS)
        row[SPHERE_CENTER:SPHERE_CENTER + 3], row[SPHERE_RADIUS] = center, radius
        return row

    @staticmethod
    def cylinder_row(origin, axis, radius: float, height: float) -> np.ndarray:
        row = np.zeros(MIRROR_PARAMS)
        row[CYLINDER_ORIGIN:CYLINDER_ORIGIN + 3] = origin
        row[CYLINDER_AXIS:CYLINDER_AXIS + 3] = axis
        row[CYLINDER_RADIUS], row[CYLINDER_HEIGHT] = radius, height
        return row


@dataclass(frozen=True)
class Triangles:
    """World-space triangles with their attributes."""

    corners: np.ndarray  # (T, 3, 3) float32
    uvs: np.ndarray  # (T, 3, 2) float32
    normals: np.ndarray  # (T, 3, 3) float32
    material: np.ndarray  # (T,) int32, -1 for mirrors
    surface: np.ndarray  # (T,) int32

    @property
    def count(self) -> int:
        return int(self.corners.shape[0])


@dataclass(frozen=True)
class Geometry:
    """One frame's geometry: object triangles and mirror triangles.

    `mirror_tris` holds every mirror as triangles (curved ones tessellated, for rasterizing);
    `mirror_exact` marks those the ray tracer intersects as triangles (mesh mirrors); it
    intersects planar, sphere and cylinder mirrors exactly, in numba.
    """

    objects: Triangles
    mirror_tris: Triangles
    mirror_exact: np.ndarray  # (Tm,) bool
    key: tuple  # equal keys -> identical geometry (lets techniques keep acceleration structures)
    # closed pieces (Mesh.pieces: a solid, or each closed part of a composite such as the
    # music room's clutter), faces all turned outward: seen from outside its box, a piece's
    # back faces lie behind its front faces. (K, 6) world box per piece (min x, y, z, max
    # x, y, z; NaN: no triangle), and (T,) int32 the piece of each of `all_triangles`
    # (-1: open); None without pieces
    closed_boxes: np.ndarray | None = None
    closed_piece: np.ndarray | None = None

    def all_triangles(self) -> Triangles:
        """Objects then mirrors, concatenated once per Geometry (a static scene's geometry
        is one object for all its frames: rebuilding this took 14 ms a frame at 1M
        triangles). Shared: callers must not write into it."""
        cached = self.__dict__.get("_all_triangles")
        if cached is None:
            o, m = self.objects, self.mirror_tris
            cached = Triangles(
                *(np.concatenate([getattr(o, f), getattr(m, f)]) for f in
                  ("corners", "uvs", "normals", "material", "surface"))
            )
            object.__setattr__(self, "_all_triangles", cached)
        return cached


@dataclass
class Scene:
    """Everything a technique needs, as arrays; geometry is fetched per frame (objects move)."""

    name: str
    source: str  # the scene file path
    shading: int
    background: np.ndarray  # (3,) float32
    ambient: float
    materials: Materials
    lights: Lights
    mirrors: Mirrors
    surface_names: list[str]
    n_objects: int
    frame_count: int
    scene_hash: str  # everything: config and referenced files
    content_hash: str  # what the scene looks like: no camera, technique or output
    room_bounds: np.ndarray | None  # (2, 3) bounds of `room` objects at frame 0
    geometry_at: Callable[[int], Geometry] = field(repr=False)
    # per mirror index, for linear extrusions: (profile points (N, 2) in local x, z, their
    # unit normals (N, 2), local -> world 4x4, height); the virtual technique searches them
    mirror_profiles: dict = field(default_factory=dict)

    def geometry(self, frame_index: int) -> Geometry:
        return self.geometry_at(frame_index)


def scene_extent(scene: Scene) -> tuple[float, float]:
    """(near, far) for map captures: from the size of the scene's geometry at frame 0."""
    tris = scene.geometry(0).all_triangles().corners.reshape(-1, 3)
    diag = float(np.linalg.norm(tris.max(axis=0) - tris.min(axis=0))) if len(tris) else 1.0
    return 1e-4 * diag, 4.0 * diag
