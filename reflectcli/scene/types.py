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

    params (float64) columns: planar: n xyz, d, then corners p00 p10 p11 p01 (xyz each);
    sphere: center xyz, radius; cylinder: origin xyz, axis xyz (unit), radius, height;
    mesh: unused (its triangles are in Geometry.mirror_tris).
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
        return self.params[k, :3].astype(np.float64), float(self.params[k, 3])

    def corners(self, k: int) -> np.ndarray:
        """Planar mirror k's corners p00, p10, p11, p01 (4, 3), world."""
        return self.params[k, 4:16].reshape(4, 3)

    def sphere(self, k: int) -> tuple[np.ndarray, float]:
        """Sphere mirror k's (center (3,), radius)."""
        return self.params[k, :3], self.params[k, 3]

    def cylinder(self, k: int) -> tuple[np.ndarray, np.ndarray, float, float]:
        """Cylinder mirror k's (origin (3,), unit axis (3,), radius, height)."""
        p = self.params[k]
        return p[:3], p[3:6], p[6], p[7]

    @staticmethod
    def planar_row(n, d: float, corners) -> np.ndarray:
        row = np.zeros(MIRROR_PARAMS)
        row[:16] = (*n, d, *np.asarray(corners).reshape(-1))
        return row

    @staticmethod
    def sphere_row(center, radius: float) -> np.ndarray:
        row = np.zeros(MIRROR_PARAMS)
        row[:4] = (*center, radius)
        return row

    @staticmethod
    def cylinder_row(origin, axis, radius: float, height: float) -> np.ndarray:
        row = np.zeros(MIRROR_PARAMS)
        row[:8] = (*origin, *axis, radius, height)
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

    def all_triangles(self) -> Triangles:
        o, m = self.objects, self.mirror_tris
        return Triangles(
            *(np.concatenate([getattr(o, f), getattr(m, f)]) for f in
              ("corners", "uvs", "normals", "material", "surface"))
        )


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
