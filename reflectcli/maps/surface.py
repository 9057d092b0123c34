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

import math

import numpy as np
from numba import njit, prange

from ..camera import Camera
from ..raster.rasterize import RasterBuffers, RasterWorkspace
from ..raster.rasterize.buffers import scratch
from ..raster.shade import shade_buffers
from ..scene.types import Scene, Triangles


def surface_colors(triangle: np.ndarray, camera: Camera, reflection: np.ndarray,
                   mirrored_eye: np.ndarray, plane: tuple[np.ndarray, float],
                   triangles: Triangles, scene: Scene,
                   workspace: RasterWorkspace | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(rgb (H, W, 3) float32, shaded (H, W) bool) for the pixels whose `triangle` (H, W,
    index into `triangles`, -1: none) their reflected ray meets in front of the mirror
    (`plane` = (unit normal, d), world); rgb is set only where shaded. `workspace`: where
    the arrays are kept across calls (the returned ones then valid until the next call);
    none is read where this call did not write it (b1, b2 and depth are written, and read,
    only where a hit is kept)."""
    h, w = triangle.shape
    b1 = scratch(workspace, "surface_b1", (h, w), np.float32)
    b2 = scratch(workspace, "surface_b2", (h, w), np.float32)
    depth = scratch(workspace, "surface_depth", (h, w), np.float32)
    hit = scratch(workspace, "surface_hit", (h, w), np.int32)
    np.copyto(hit, triangle)
    right, up, back = camera.basis()
    t = math.tan(math.radians(camera.fov_y) / 2.0)
    # the camera's pixel-center rays (world), reflected: d = x_ndc * X + y_ndc * Y - Z
    r3 = np.asarray(reflection[:3, :3], np.float64)
    axes = np.stack([r3 @ (right * t * camera.aspect), r3 @ (up * t), r3 @ back])
    n, d = plane
    _intersect(triangle, axes, np.asarray(mirrored_eye, np.float64), triangles.corners,
               np.asarray(n, np.float64), float(d), hit, b1, b2, depth)
    ok = np.greater_equal(hit, 0, out=scratch(workspace, "surface_ok", (h, w), np.bool_))
    # only the pixels that found their point are shaded (the rest of rgb is left unset)
    rgb, _ = shade_buffers(RasterBuffers(hit, b1, b2, depth), triangles, scene, mirrored_eye,
                           stencil=ok, out=(scratch(workspace, "surface_rgb", (h, w, 3),
                                                    np.float32),
                                            scratch(workspace, "surface_ids", (h, w),
                                                    np.int32)))
    return rgb, ok


@njit(cache=True, parallel=True)
def _intersect(triangle, axes, origin, corners, normal, offset, hit, b1, b2, depth):
    """Moller-Trumbore against the triangle's plane (barycentrics unbounded, clamped to
    [-1, 2] so that a neighbour's point a little past the edge extrapolates sanely)."""
    h, w = triangle.shape
    ox, oy, oz = origin[0], origin[1], origin[2]
    side = normal[0] * ox + normal[1] * oy + normal[2] * oz + offset  # the origin's, signed
    for y in prange(h):
        yn = 1.0 - 2.0 * (y + 0.5) / h
        for x in range(w):
            t = triangle[y, x]
            if t < 0:
                continue
            xn = 2.0 * (x + 0.5) / w - 1.0
            dx = xn * axes[0, 0] + yn * axes[1, 0] - axes[2, 0]
            dy = xn * axes[0, 1] + yn * axes[1, 1] - axes[2, 1]
            dz = xn * axes[0, 2] + yn * axes[1, 2] - axes[2, 2]
            v0x, v0y, v0z = corners[t, 0, 0], corners[t, 0, 1], corners[t, 0, 2]
            e1x, e1y, e1z = corners[t, 1, 0] - v0x, corners[t, 1, 1] - v0y, corners[t, 1, 2] - v0z
            e2x, e2y, e2z = corners[t, 2, 0] - v0x, corners[t, 2, 1] - v0y, corners[t, 2, 2] - v0z
            px = dy * e2z - dz * e2y
            py = dz * e2x - dx * e2z
            pz = dx * e2y - dy * e2x
            det = e1x * px + e1y * py + e1z * pz
            scale = (math.sqrt(e1x * e1x + e1y * e1y + e1z * e1z)
                     * math.sqrt(e2x * e2x + e2y * e2y + e2z * e2z)
                     * math.sqrt(dx * dx + dy * dy + dz * dz))
            if abs(det) <= 1e-12 * scale:
                hit[y, x] = -1
                continue
            inv = 1.0 / det
            sx, sy, sz = ox - v0x, oy - v0y, oz - v0z
            u = (sx * px + sy * py + sz * pz) * inv
            qx = sy * e1z - sz * e1y
            qy = sz * e1x - sx * e1z
            qz = sx * e1y - sy * e1x
            v = (dx * qx + dy * qy + dz * qz) * inv
            dist = (e2x * qx + e2y * qy + e2z * qz) * inv
            # beyond the mirror: where the ray crosses its plane, from the origin's side
            dn = normal[0] * dx + normal[1] * dy + normal[2] * dz
            crossing = -side / dn if dn != 0.0 else np.inf
            if not (dist > 0.0 and dist > crossing):
                hit[y, x] = -1
                continue
            b1[y, x] = min(max(u, -1.0), 2.0)
            b2[y, x] = min(max(v, -1.0), 2.0)
            depth[y, x] = dist
