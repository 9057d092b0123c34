"""Plain rasterization, no reflections: the shared first pass of every raster technique.

| parameter | type | default | meaning |
|---|---|---|---|
| (none) | | | mirrors show (1 - r) * base, like `raytrace` with `max_depth = 0` |

Useful as a baseline for cost and to check the rasterizer against the ray tracer.
"""

from __future__ import annotations

import time
from typing import Literal

import numpy as np
from pydantic import ConfigDict

from ..camera import Camera
from ..config.base import Strict
from ..frame import Frame
from ..raster.rasterize import FLAG_MIRROR, rasterize
from ..raster.shade import shade_buffers
from ..scene.types import Scene
from .base import Technique


class RasterParams(Strict):
    model_config = ConfigDict(title="raster")

    name: Literal["raster"] = "raster"


def render_primary(scene: Scene, frame: int, camera: Camera) -> Frame:
    """Rasterize and shade the scene from `camera`; mirror pixels hold (1 - r) * base."""
    t0 = time.perf_counter()
    tris = scene.geometry(frame).all_triangles()
    world_to_clip = camera.projection_matrix() @ camera.view_matrix()
    flags = np.where(tris.surface >= scene.n_objects, FLAG_MIRROR, 0).astype(np.uint8)
    buffers = rasterize(tris.corners, flags, world_to_clip, camera.width, camera.height)
    t1 = time.perf_counter()
    rgb, surface = shade_buffers(buffers, tris, scene, camera.eye)
    t2 = time.perf_counter()
    return Frame(
        rgb=rgb, depth=buffers.depth, surface=surface, mirror_mask=surface >= scene.n_objects,
        timings={"rasterize": t1 - t0, "shade": t2 - t1},
        stats={"triangles": tris.count},
    )


class Raster(Technique):
    name = "raster"
    Params = RasterParams

    def prepare(self, scene: Scene) -> Scene:
        return scene

    def render(self, state: Scene, frame: int, camera: Camera) -> Frame:
        return render_primary(state, frame, camera)
