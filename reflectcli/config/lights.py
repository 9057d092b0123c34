"""Lights for `shading = "lambert"` (no shadows)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from .base import Color, Strict, Vec3


class PointLight(Strict):
    """Radiant intensity falls off with the inverse square of the distance."""

    kind: Literal["point"]
    position: Vec3
    color: Color = (1.0, 1.0, 1.0)
    intensity: float = Field(default=1.0, ge=0.0)


class DirectionalLight(Strict):
    """`direction` is the way the light travels (from the light toward the scene)."""

    kind: Literal["directional"]
    direction: Vec3
    color: Color = (1.0, 1.0, 1.0)
    intensity: float = Field(default=1.0, ge=0.0)


Light = Annotated[PointLight | DirectionalLight, Field(discriminator="kind")]
