"""Camera and camera-path sections."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from .base import PositiveInt, Strict, Vec3


class CameraKey(Strict):
    """One keyframe of a camera path; omitted fields keep the camera's own values."""

    eye: Vec3
    target: Vec3
    up: Vec3 | None = None
    fov_y: float | None = Field(default=None, gt=0.0, lt=180.0)


class CameraPath(Strict):
    """A walkthrough: frame i of `frames` sits at i/(frames-1) along the keys, spaced evenly."""

    frames: PositiveInt = 1
    interpolation: Literal["linear", "catmull-rom"] = "catmull-rom"
    keys: list[CameraKey] = Field(min_length=1)


class CameraConfig(Strict):
    eye: Vec3
    target: Vec3
    up: Vec3 = (0.0, 1.0, 0.0)
    fov_y: float = Field(default=55.0, gt=0.0, lt=180.0, description="full vertical angle, deg")
    width: PositiveInt = 640
    height: PositiveInt = 480
    near: float = Field(default=0.01, gt=0.0)
    far: float = Field(default=100.0, gt=0.0)
    path: CameraPath | None = None

    @model_validator(mode="after")
    def _near_before_far(self) -> CameraConfig:
        if self.far <= self.near:
            raise ValueError("far must be > near")
        return self

    @property
    def frame_count(self) -> int:
        return self.path.frames if self.path else 1
