"""The rasterizer alone as a technique (parameters: the package docstring)."""

from __future__ import annotations

from ...camera import Camera
from ...frame import Frame
from ...raster.primary import render_primary
from ...scene.types import Scene
from ..base import Technique
from . import RasterParams


class Raster(Technique):
    name = "raster"
    Params = RasterParams

    def prepare(self, scene: Scene) -> Scene:
        return scene

    def render(self, state: Scene, frame_index: int, camera: Camera) -> Frame:
        return render_primary(state, frame_index, camera).frame
