"""Whitted ray tracing: the ground truth every other technique is measured against.

| parameter | type | default | meaning |
|---|---|---|---|
| `max_depth` | int >= 0 | 4 | mirror bounces followed; beyond, a mirror shows (1 - r) * base |
| `samples` | int >= 1 | 1 | samples per pixel axis (s x s grid); Z, A, ids from the center |

Triangles are intersected by Embree (objects and exact mirror triangles in two scenes, so a
mirror flush with a wall wins the depth tie); spheres and cylinders exactly in numba.
Primary rays run from the near plane to the far plane along each pixel center, like the
rasterizer's clipping, so both see the same surfaces.
"""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, Field

from ..camera import Camera
from ..config.base import Strict
from ..frame import Frame
from ..scene.types import Scene
from ..trace.tracer import build_accelerators, trace_frame
from .base import Technique


class RaytraceParams(Strict):
    model_config = ConfigDict(title="raytrace")

    name: Literal["raytrace"] = "raytrace"
    max_depth: int = Field(default=4, ge=0, le=64, description="mirror bounces followed")
    samples: int = Field(default=1, ge=1, le=16, description="samples per pixel axis (s x s)")


class Raytrace(Technique):
    name = "raytrace"
    Params = RaytraceParams

    def prepare(self, scene: Scene) -> dict:
        return {"scene": scene, "accel": None}

    def render(self, state: dict, frame: int, camera: Camera) -> Frame:
        scene: Scene = state["scene"]
        geometry = scene.geometry(frame)
        built = 0.0
        if state["accel"] is None or state["accel"].key != geometry.key:
            state["accel"] = build_accelerators(geometry)
            built = state["accel"].build_seconds
        result = trace_frame(scene, geometry, state["accel"], camera, self.params.max_depth,
                             self.params.samples, self.threads)
        result.timings["embree_build"] = built
        return result
