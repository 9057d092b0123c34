"""Layered distance cube maps: colour, eye depth and surface id of the first `layers`
surfaces along every cube-map direction, captured by depth peeling with the shared rasterizer.

Faces and texel layout are those of `maps/cube.py` (+x, -x, +y, -y, +z, -z; each an ordinary
90-degree camera image from the capture point). Per layer, face and texel (all float32 or
int32 plain arrays, shape (L, 6, R, R[, 3])):

- `color`: the shaded colour of the surface (mirrors show (1 - r) * base: no reflections);
- `depth`: its eye-space depth w along the face's axis (map space), +inf where no surface;
- `surface`: its surface id (objects, then mirrors), -1 where no surface.

Layer 0 is an ordinary z-buffer pass; layer k rasterizes again with layer k-1's depth as a
floor (fragments at or in front of it are dropped, `rasterize(depth_floor=...)`), so layer k
holds the k-th surface along the texel's center ray. The floor is raised by PEEL_EPSILON
(relative) so that a surface is never peeled twice by rounding where two triangles meet.

The search (`maps/distance_search.py`) reads 1 / w, not the Euclidean distance: for a plane,
1 / w is linear in face (screen) coordinates, so bilinear interpolation of it is exact.
"""

from __future__ import annotations

import numpy as np

from ..raster.rasterize import FLAG_SKIP, rasterize
from ..raster.shade import shade_buffers
from ..scene.types import Scene, Triangles
from .cube import face_camera

PEEL_EPSILON = 1e-5


def capture_distance_faces(
    scene: Scene, tris: Triangles, flags: np.ndarray, point: np.ndarray, resolution: int,
    layers: int, exclude_surface: int, near: float, far: float, faces=range(6),
    out: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(color (L, 6, R, R, 3), depth (L, 6, R, R), surface (L, 6, R, R)) seen from `point`
    without surface `exclude_surface` (the reflector). Only `faces` are captured; with `out`
    the others keep their contents (time-sliced updates), else they stay empty."""
    if out is None:
        color = np.zeros((layers, 6, resolution, resolution, 3), np.float32)
        depth = np.full((layers, 6, resolution, resolution), np.inf, np.float32)
        surface = np.full((layers, 6, resolution, resolution), -1, np.int32)
    else:
        color, depth, surface = out
    pass_flags = flags | np.where(tris.surface == exclude_surface, FLAG_SKIP, 0).astype(np.uint8)
    for f in faces:
        cam = face_camera(f, point, resolution, near, far)
        clip_from_world = cam.clip_from_world()
        floor = None
        for k in range(layers):
            buffers = rasterize(tris.corners, pass_flags, clip_from_world, resolution,
                                resolution, depth_floor=floor)
            rgb, surf = shade_buffers(buffers, tris, scene, cam.eye)
            color[k, f] = rgb
            depth[k, f] = buffers.depth
            surface[k, f] = surf
            if not np.isfinite(buffers.depth).any():
                color[k + 1:, f] = 0.0
                depth[k + 1:, f] = np.inf
                surface[k + 1:, f] = -1
                break
            floor = (buffers.depth * np.float32(1.0 + PEEL_EPSILON)).astype(np.float32)
    return color, depth, surface


def inverse_depth(depth: np.ndarray) -> np.ndarray:
    """1 / w as float32, 0 where there is no surface (w = +inf)."""
    with np.errstate(divide="ignore"):
        return np.where(np.isfinite(depth), np.float32(1.0) / depth, np.float32(0.0)).astype(
            np.float32)
