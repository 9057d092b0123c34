"""Plain rasterization, no reflections: the shared first pass of every raster technique.

| parameter | type | default | meaning |
|---|---|---|---|
| (none) | | | mirrors show (1 - r) * base, like `raytrace` with `max_depth = 0` |

Useful as a baseline for cost and to check the rasterizer against the ray tracer.
"""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict

from ..camera import Camera
from ..config.base import Strict
from ..frame import Frame
from ..raster.primary import render_primary
from ..scene.types import Scene
from .base import Technique


class RasterParams(Strict):
    model_config = ConfigDict(title="raster")

    name: Literal["raster"] = "raster"


class Raster(Technique):
    name = "raster"
    Params = RasterParams

    def prepare(self, scene: Scene) -> Scene:
        return scene

    def render(self, state: Scene, frame: int, camera: Camera) -> Frame:
        return render_primary(state, frame, camera).frame
