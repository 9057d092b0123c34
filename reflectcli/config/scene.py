"""The whole scene file as one validated model."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from ..techniques.registry import TechniqueConfig, default_technique
from .base import Color, Strict
from .camera import CameraConfig
from .lights import Light
from .materials import Material
from .mirrors import MirrorConfig
from .objects import ObjectConfig
from .output import OutputConfig


class SceneSection(Strict):
    name: str = Field(pattern=r"^[A-Za-z0-9._-]+$")
    shading: Literal["unlit", "lambert"] = "unlit"
    background: Color = (0.0, 0.0, 0.0)
    ambient: float = Field(default=0.0, ge=0.0, description="lambert: ambient fraction of albedo")


class SceneConfig(Strict):
    scene: SceneSection
    camera: CameraConfig
    materials: dict[str, Material] = {}
    lights: list[Light] = []
    objects: list[ObjectConfig] = []
    mirrors: list[MirrorConfig] = []
    technique: TechniqueConfig = Field(default_factory=default_technique)
    output: OutputConfig = OutputConfig()
