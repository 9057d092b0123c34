"""Drawing virtual objects: the virtual triangles rasterized over a reflector's pixels,
with geometry in front of the reflector removed, and shaded from their original surfaces."""

from __future__ import annotations

import numpy as np

from ..camera import Camera
from ..geometry import transform_plane
from ..raster.primary import Primary
from ..raster.rasterize import FLAG_MIRROR, FLAG_SKIP, rasterize, standard_planes
from ..raster.shade import shade_buffers
from ..scene.types import Scene, Triangles


def draw_virtual(scene: Scene, primary: Primary, camera: Camera, clip_from_world: np.ndarray,
                 reflected: Triangles, virtual: np.ndarray, dropped: np.ndarray,
                 stencil: np.ndarray, sid: int, mirror_plane: np.ndarray | None,
                 reflector_test: str) -> np.ndarray:
    """(H, W, 3) colors of the virtual triangles `virtual` (T, 3, 3 world) over `stencil`
    (H, W screen); `dropped` (T,) are skipped. A planar mirror (`mirror_plane` n, d facing
    the eye) clips them exactly; a curved one applies `reflector_test`."""
    planes = standard_planes()  # clip space
    floor = None
    if mirror_plane is not None:  # the exact case: the mirror plane clips
        planes = np.vstack([planes, mirror_clip_plane(mirror_plane, camera.eye,
                                                      clip_from_world)])
    elif reflector_test == "zbuffer":
        floor = np.where(stencil, primary.buffers.depth, 0.0).astype(np.float32)
    elif reflector_test == "clip_planes":
        pts = primary.triangles.corners[primary.triangles.surface == sid].reshape(-1, 3)
        planes = np.vstack([planes, box_planes(pts, camera.eye, clip_from_world)])
    flags = np.where(reflected.surface >= scene.n_objects, FLAG_MIRROR, 0).astype(np.uint8)
    flags[dropped] |= FLAG_SKIP
    buffers = rasterize(virtual.astype(np.float32), flags, clip_from_world, camera.width,
                        camera.height, planes, mask=stencil, depth_floor=floor)
    colors, _ = shade_buffers(buffers, reflected, scene, camera.eye)
    return colors


def mirror_clip_plane(plane: np.ndarray, eye: np.ndarray,
                      clip_from_world: np.ndarray) -> np.ndarray:
    """Clip-space plane keeping what lies behind a planar mirror (n, d; world, n . eye + d
    >= 0), moved a little behind it so the mirror's own wall is not reflected."""
    n, d = plane[:3], float(plane[3])
    offset = 1e-4 * (1.0 + abs(d) + float(np.abs(eye).max()))
    clip = transform_plane(np.append(-n, -d - offset), clip_from_world)
    return clip / np.abs(clip).max()


def box_planes(points: np.ndarray, eye: np.ndarray, clip_from_world: np.ndarray) -> np.ndarray:
    """Clip-space planes keeping what lies behind the reflector's bounding-box faces that
    face the eye (at most three of the six); `points` (N, 3) world."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    planes = []
    for axis in range(3):
        for sign, bound in ((1.0, hi[axis]), (-1.0, lo[axis])):
            if sign * (eye[axis] - bound) > 0:  # this face looks at the eye
                plane = np.zeros(4)  # world
                plane[axis] = -sign
                plane[3] = sign * bound
                clip = transform_plane(plane, clip_from_world)
                planes.append(clip / np.abs(clip).max())
    return np.array(planes).reshape(-1, 4)
