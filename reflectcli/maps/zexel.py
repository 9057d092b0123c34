"""Depth-preserving reflection maps: color + eye-space depth per zexel, captured through a
planar mirror from viewpoints behind it (Bastos & Stuerzlinger, sec. 4).

A map is an ordinary camera image of the scene in front of the mirror, taken from a
viewpoint on the mirror's back side looking through the mirror as through a window, with
the mirror plane as the (oblique) near plane, so nothing behind the mirror is captured.
Depth is the eye-space depth along the map camera's axis (+inf where nothing was hit); the
warp derives the generalized disparity 1 / depth from it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..camera import Camera, normalize, reflection_pass_matrices
from ..raster.rasterize import FLAG_MIRROR, FLAG_SKIP, rasterize
from ..raster.shade import shade_buffers
from ..scene.types import Scene
from .warp import SAME_SURFACE


@dataclass
class ZexelMap:
    camera: Camera  # the map's camera (world space); its image is the map
    color: np.ndarray  # (H, W, 3) float32, linear
    depth: np.ndarray  # (H, W) float32, eye-space depth along the camera axis, +inf if empty
    # (H, W) int32: the triangle (index into the scene's frame-0 triangles) each zexel saw,
    # -1 if empty; lets `reconstruct = "surface"` shade the exact point under each pixel
    triangle: np.ndarray | None = None


@dataclass(frozen=True)
class MirrorFrame:
    """A planar mirror's center, unit normal (its front), right and up (world)."""

    center: np.ndarray
    normal: np.ndarray
    right: np.ndarray
    up: np.ndarray
    corners: np.ndarray  # (4, 3) p00 p10 p11 p01

    @property
    def plane(self) -> np.ndarray:
        return np.append(self.normal, -self.normal @ self.center)

    @property
    def diagonal(self) -> float:
        return float(np.linalg.norm(self.corners[2] - self.corners[0]))


def mirror_frame(scene: Scene, k: int) -> MirrorFrame:
    corners = scene.mirrors.corners(k).astype(np.float64)
    n, _ = scene.mirrors.plane(k)
    up = normalize(corners[3] - corners[0])
    right = np.cross(up, n)
    return MirrorFrame(corners.mean(axis=0), n, right, up, corners)


def viewpoints(frame: MirrorFrame, count: int, layout: str, radius: float, spread: float):
    """(count, 3) world points on a hemisphere of `radius` behind the mirror, within `spread`
    degrees of its axis; count = 1 is the point on the axis.

    grid: a sqrt(count) x sqrt(count) grid over the cap's tangent square (count a square);
    fibonacci: a golden-angle spiral over the cap (any count)."""
    axis = -frame.normal
    if count == 1:
        return (frame.center + radius * axis)[None]
    tan_spread = math.tan(math.radians(spread))
    if layout == "grid":
        n = math.isqrt(count)
        s = np.linspace(-1.0, 1.0, n)
        u, v = np.meshgrid(s, s)
        offsets = tan_spread * (u.reshape(-1, 1) * frame.right + v.reshape(-1, 1) * frame.up)
    else:
        i = np.arange(count) + 0.5
        cos_max = math.cos(math.radians(spread))
        cos_t = 1.0 - (1.0 - cos_max) * i / count
        r = np.sqrt(1.0 - cos_t**2) / cos_t
        phi = i * math.pi * (3.0 - math.sqrt(5.0))
        offsets = r[:, None] * (np.cos(phi)[:, None] * frame.right
                                + np.sin(phi)[:, None] * frame.up)
    dirs = axis + offsets
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    return frame.center + radius * dirs


def map_camera(frame: MirrorFrame, viewpoint: np.ndarray, resolution: int, near: float,
               far: float) -> Camera:
    """A square camera at `viewpoint` aimed at the mirror's center whose frustum covers it."""
    cam = Camera(viewpoint, frame.center, frame.up, 90.0, resolution, resolution, near, far)
    view = cam.view_matrix()
    eye_corners = frame.corners @ view[:3, :3].T + view[:3, 3]
    depth = -eye_corners[:, 2]
    half = np.max(np.abs(eye_corners[:, :2]) / depth[:, None])
    fov = 2.0 * math.degrees(math.atan(half * 1.02))  # 2% margin around the mirror
    return Camera(viewpoint, frame.center, frame.up, fov, resolution, resolution, near, far)


def capture_map(scene: Scene, k: int, camera: Camera, frame_index: int = 0) -> ZexelMap:
    """Render the scene in front of mirror k from `camera` (behind the mirror), mirror plane
    as the oblique near plane; the mirror itself is left out, other mirrors show their base."""
    mf = mirror_frame(scene, k)
    plane = mf.plane
    if plane[:3] @ camera.eye + plane[3] > 0:
        raise ValueError("map viewpoint must lie behind the mirror")
    offset = 1e-4 * (1.0 + abs(plane[3]) + float(np.abs(camera.eye).max()))
    clip_from_world, planes = reflection_pass_matrices(
        camera, np.eye(4), plane - np.array([0, 0, 0, offset]), "oblique")
    tris = scene.geometry(frame_index).all_triangles()
    flags = np.where(tris.surface >= scene.n_objects, FLAG_MIRROR, 0).astype(np.uint8)
    flags |= np.where(tris.surface == scene.n_objects + k, FLAG_SKIP, 0).astype(np.uint8)
    buffers = rasterize(tris.corners, flags, clip_from_world, camera.width, camera.height, planes)
    color, _ = shade_buffers(buffers, tris, scene, camera.eye)
    depth = buffers.depth.copy()
    depth[buffers.triangle < 0] = np.inf
    return ZexelMap(camera, color, depth, buffers.triangle.astype(np.int32))


def coarser(zmap: ZexelMap) -> ZexelMap:
    """The next mip level: half the resolution, each zexel made from its 2x2 block.

    Where the four zexels lie on one surface (eye depths within SAME_SURFACE of each other)
    the coarse zexel is their box filter: mean color, and the depth whose disparity 1/z is
    their mean, which on a plane is exactly the depth at the coarse pixel's center (1/z is
    affine in screen space). Across a discontinuity it is the nearest of the four, so
    silhouettes stay in front rather than zexels floating between surfaces; that one moves
    by up to half a coarse zexel when it is reprojected through the coarse pixel's center."""
    h, w = zmap.depth.shape
    h2, w2 = h // 2, w // 2
    flat = (zmap.depth[: 2 * h2, : 2 * w2].reshape(h2, 2, w2, 2).transpose(0, 2, 1, 3)
            .reshape(h2, w2, 4))
    colors = (zmap.color[: 2 * h2, : 2 * w2].reshape(h2, 2, w2, 2, 3)
              .transpose(0, 2, 1, 3, 4).reshape(h2, w2, 4, 3))
    pick = np.argmin(flat, axis=2)
    new_depth = np.take_along_axis(flat, pick[..., None], axis=2)[..., 0]
    new_color = np.take_along_axis(colors, pick[..., None, None], axis=2)[:, :, 0]
    near, far = flat.min(axis=2), flat.max(axis=2)
    with np.errstate(invalid="ignore"):
        one_surface = np.isfinite(far) & (far <= near * (1.0 + SAME_SURFACE))
    new_depth[one_surface] = 1.0 / np.mean(1.0 / flat[one_surface], axis=1)
    new_color[one_surface] = colors[one_surface].mean(axis=1)
    triangle = None
    if zmap.triangle is not None:  # the picked zexel's (on one surface, any will do)
        blocks = (zmap.triangle[: 2 * h2, : 2 * w2].reshape(h2, 2, w2, 2)
                  .transpose(0, 2, 1, 3).reshape(h2, w2, 4))
        triangle = np.ascontiguousarray(
            np.take_along_axis(blocks, pick[..., None], axis=2)[..., 0])
    cam = zmap.camera
    camera = Camera(cam.eye, cam.target, cam.up, cam.fov_y, w2, h2, cam.near, cam.far)
    return ZexelMap(camera, np.ascontiguousarray(new_color, np.float32),
                    np.ascontiguousarray(new_depth, np.float32), triangle)


def mip_pyramid(zmap: ZexelMap, smallest: int = 16) -> list[ZexelMap]:
    """[full map, half, quarter, ...] down to `smallest` zexels a side."""
    levels = [zmap]
    while min(levels[-1].depth.shape) // 2 >= smallest:
        levels.append(coarser(levels[-1]))
    return levels
