"""The rasterizer alone as a technique (parameters: the package docstring)."""

from __future__ import annotations

from ...camera import Camera
from ...frame import Frame
from ...raster.primary import render_primary
from ...raster.rasterize import RasterWorkspace
from ...scene.types import Scene
from ..base import Technique
from . import RasterParams


class Raster(Technique):
    name = "raster"
    Params = RasterParams
    _primary_ws: RasterWorkspace | None = None

    def prepare(self, scene: Scene) -> Scene:
        # the rasterizer's scratch and triangle ids kept across frames (the frame keeps
        # the depth buffer: fresh)
        self._primary_ws = RasterWorkspace(ids=True)
        return scene

    def render(self, state: Scene, frame_index: int, camera: Camera) -> Frame:
        return render_primary(state, frame_index, camera, self._primary_ws).frame
