"""Materials: solid color, checker in UV space, image texture (sRGB decoded on load)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Discriminator, Field, Tag

from .base import Color, Strict, array_of


class SolidMaterial(Strict):
    kind: Literal["solid"] = "solid"
    color: Color = (0.8, 0.8, 0.8)


class CheckerMaterial(Strict):
    """Square (floor(u*su), floor(v*sv)); color0 where i+j is even."""

    kind: Literal["checker"]
    color0: Color = (0.0, 0.0, 0.0)
    color1: Color = (1.0, 1.0, 1.0)
    scale: array_of(Annotated[float, Field(gt=0)], Annotated[float, Field(gt=0)]) = (8.0, 8.0)


class TextureMaterial(Strict):
    """An image read with OpenImageIO, relative to the scene file; repeats outside [0, 1]."""

    kind: Literal["texture"]
    path: str
    srgb: bool = Field(default=True, description="decode sRGB to linear on load")
    filter: Literal["nearest", "bilinear"] = "bilinear"
    scale: array_of(Annotated[float, Field(gt=0)], Annotated[float, Field(gt=0)]) = (1.0, 1.0)


def _kind(value) -> str:
    """A material without `kind` is solid (its documented default)."""
    if isinstance(value, dict):
        return value.get("kind", "solid")
    return getattr(value, "kind", "solid")


Material = Annotated[
    Annotated[SolidMaterial, Tag("solid")]
    | Annotated[CheckerMaterial, Tag("checker")]
    | Annotated[TextureMaterial, Tag("texture")],
    Discriminator(_kind),
]
