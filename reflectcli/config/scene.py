"""The whole scene file as one validated model.

config/ knows no technique: `SceneConfig` leaves `technique` open, and `scene_model_with`
builds the model a scene file is validated against from a mapping of technique names to
their Params models (given by the technique registry, a layer above).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any, Literal, Union

from pydantic import BaseModel, Field, create_model

from .base import Color, Strict
from .camera import CameraConfig
from .lights import Light
from .materials import Material
from .mirrors import MirrorConfig
from .names import NAME_PATTERN
from .objects import ObjectConfig
from .output import OutputConfig


class SceneSection(Strict):
    name: str = Field(pattern=NAME_PATTERN)
    shading: Literal["unlit", "lambert"] = "unlit"
    background: Color = (0.0, 0.0, 0.0)
    ambient: float = Field(default=0.0, ge=0.0, description="lambert: ambient fraction of albedo")


class SceneConfig(Strict):
    """A scene file. `technique` is one technique's Params model (see `scene_model_with`)."""

    scene: SceneSection
    camera: CameraConfig
    materials: dict[str, Material] = {}
    lights: list[Light] = []
    objects: list[ObjectConfig] = []
    mirrors: list[MirrorConfig] = []
    technique: Any = None
    output: OutputConfig = OutputConfig()


def scene_model_with(params: Mapping[str, type[BaseModel]], default: str) -> type[SceneConfig]:
    """SceneConfig whose `technique` is the tagged union of `params` (by `name`), defaulting
    to `params[default]()`."""
    union = Annotated[Union[tuple(params.values())], Field(discriminator="name")]  # noqa: UP007
    return create_model(
        "SceneConfig", __base__=SceneConfig, __module__=__name__,
        technique=(union, Field(default_factory=params[default])),
    )
