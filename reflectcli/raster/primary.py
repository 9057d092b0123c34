"""The first pass every raster technique shares: the scene from the real camera."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..camera import Camera
from ..frame import Frame
from ..scene.types import Geometry, Scene, Triangles
from .closed import primary_pass_flags
from .rasterize import RasterBuffers, RasterWorkspace, rasterize
from .shade import shade_buffers


@dataclass
class Primary:
    frame: Frame  # mirror pixels hold (1 - r) * base; techniques add r * reflected
    buffers: RasterBuffers
    triangles: Triangles
    flags: np.ndarray  # per-triangle rasterizer flags (mirrors marked)
    # the frame's geometry (`triangles` is its all_triangles()): what later passes draw
    # and cull (rerender's reflection passes, ssr's and ppr's rerender fallback)
    geometry: Geometry | None = None


def render_primary(scene: Scene, frame_index: int, camera: Camera,
                   workspace: RasterWorkspace | None = None) -> Primary:
    """`workspace`: the rasterizer's scratch kept across frames (outputs stay fresh: the
    frame keeps the depth buffer; a workspace made with `ids=True` keeps the triangle ids
    and barycentrics too, the returned buffers' then valid until its next pass)."""
    t0 = time.perf_counter()
    geometry = scene.geometry(frame_index)
    tris = geometry.all_triangles()
    # closed surfaces seen from outside: their back faces culled (closed.py); the flags
    # kept while the triangles and those surfaces stay
    flags, draw_flags = primary_pass_flags(geometry, camera, scene.n_objects, workspace)
    clip_from_world = camera.clip_from_world()
    buffers = rasterize(tris.corners, draw_flags, clip_from_world, camera.width, camera.height,
                        workspace=workspace)
    t1 = time.perf_counter()
    rgb, surface = shade_buffers(buffers, tris, scene, camera.eye)
    t2 = time.perf_counter()
    result = Frame(
        rgb=rgb, depth=buffers.depth, surface=surface, mirror_mask=surface >= scene.n_objects,
        timings={"rasterize": t1 - t0, "shade": t2 - t1}, stats={"triangles": tris.count},
    )
    return Primary(result, buffers, tris, flags, geometry)
