"""Surface reconstruction for warped zexels: each reached pixel shades the exact point where
its own reflected ray meets the plane of the triangle its zexel saw.

A forward warp moves point samples; where a texture has hard edges, the sample nearest a
pixel center can lie across an edge from it, a one-pixel seam (the error floor of color
zexels). Knowing the triangle, the pixel can instead intersect its ray (world space, from the
mirrored eye through the pixel center, reflected) with that triangle's plane and shade the
point there with the rasterizer's shading: exact wherever the triangle, or a coplanar
neighbour with the same texture mapping, is the surface under the pixel center.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..camera import Camera
from ..raster.rasterize import RasterBuffers
from ..raster.shade import shade_buffers
from ..scene.types import Scene, Triangles


def surface_colors(triangle: np.ndarray, camera: Camera, reflection: np.ndarray,
                   mirrored_eye: np.ndarray, triangles: Triangles,
                   scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """(rgb (H, W, 3) float32, shaded (H, W) bool) for the pixels whose `triangle` (H, W,
    index into `triangles`, -1: none) their reflected ray meets in front of the mirror."""
    dirs = camera.pixel_directions(1)[:, :, 0]  # world, through the pixel centers
    h, w = triangle.shape
    b1 = np.zeros((h, w), np.float32)
    b2 = np.zeros((h, w), np.float32)
    depth = np.full((h, w), np.inf, np.float32)
    hit = triangle.copy()
    _intersect(triangle, np.ascontiguousarray(dirs, np.float64),
               np.ascontiguousarray(reflection[:3, :3], np.float64),
               np.asarray(mirrored_eye, np.float64), triangles.corners, hit, b1, b2, depth)
    rgb, _ = shade_buffers(RasterBuffers(hit, b1, b2, depth), triangles, scene, mirrored_eye)
    return rgb, hit >= 0


@njit(cache=True, parallel=True)
def _intersect(triangle, dirs, r3, origin, corners, hit, b1, b2, depth):
    """Moller-Trumbore against the triangle's plane (barycentrics unbounded, clamped to
    [-1, 2] so that a neighbour's point a little past the edge extrapolates sanely)."""
    h, w = triangle.shape
    for y in prange(h):
        for x in range(w):
            t = triangle[y, x]
            if t < 0:
                continue
            d = r3 @ dirs[y, x]
            v0 = corners[t, 0].astype(np.float64)
            e1 = corners[t, 1].astype(np.float64) - v0
            e2 = corners[t, 2].astype(np.float64) - v0
            p = np.cross(d, e2)
            det = e1 @ p
            if abs(det) < 1e-12 * (np.sqrt(e1 @ e1) * np.sqrt(e2 @ e2) * np.sqrt(d @ d)):
                hit[y, x] = -1
                continue
            inv = 1.0 / det
            s = origin - v0
            u = (s @ p) * inv
            q = np.cross(s, e1)
            v = (d @ q) * inv
            dist = (e2 @ q) * inv
            if not dist > 0.0:
                hit[y, x] = -1
                continue
            b1[y, x] = min(max(u, -1.0), 2.0)
            b2[y, x] = min(max(v, -1.0), 2.0)
            depth[y, x] = dist
