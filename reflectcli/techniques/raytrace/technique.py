"""The ray tracer's technique class (parameters: the package docstring)."""

from __future__ import annotations

from dataclasses import dataclass

from ...camera import Camera
from ...frame import Frame
from ...scene.types import Scene
from ...trace.tracer import Accelerators, build_accelerators, trace_frame
from ..base import Technique
from . import RaytraceParams


@dataclass
class RaytraceState:
    scene: Scene
    accel: Accelerators | None = None  # rebuilt when the geometry's key changes


class Raytrace(Technique):
    name = "raytrace"
    Params = RaytraceParams

    @property
    def _fast(self) -> bool:
        return self.params.embree == "fast"

    def prepare(self, scene: Scene) -> RaytraceState:
        """The Embree scenes of frame 0's geometry are built here, in the one-time work:
        a static scene never builds again, and frame 0's time holds no build."""
        state = RaytraceState(scene)
        if scene.frame_count:
            state.accel = build_accelerators(scene.geometry(0), self._fast)
        return state

    def render(self, state: RaytraceState, frame_index: int, camera: Camera) -> Frame:
        scene = state.scene
        geometry = scene.geometry(frame_index)
        built = 0.0
        if state.accel is None or state.accel.key != geometry.key:
            kept = state.accel.buffers if state.accel is not None else None
            state.accel = build_accelerators(geometry, self._fast)
            if kept is not None:  # work arrays outlive the geometry (moving objects)
                state.accel.buffers = kept
            built = state.accel.build_seconds
        result = trace_frame(scene, geometry, state.accel, camera, self.params.max_depth,
                             self.params.samples, self.threads)
        result.timings["embree_build"] = built
        return result
