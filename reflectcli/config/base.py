"""Shared pydantic base and small field types for every config model."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

Vec3 = tuple[float, float, float]
Vec2 = tuple[float, float]
Color = Annotated[tuple[float, float, float], Field(description="linear RGB")]
PositiveInt = Annotated[int, Field(gt=0)]
UnitFloat = Annotated[float, Field(ge=0.0, le=1.0)]


class Strict(BaseModel):
    """Unknown keys are errors (pbrt-style): a typo must not silently fall back to a default.
    NaN and infinity are errors too: every range check would let them through."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)
