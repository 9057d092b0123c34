"""The technique registry: name -> technique class, and the config union built from it.

Each technique module owns a pydantic `Params` model whose `name` literal is the
discriminator, so `[technique]` in a scene validates against that technique's own fields.
"""

from __future__ import annotations

from typing import Annotated, Union

from pydantic import BaseModel, Field

from .base import Technique
from .dprm import Dprm
from .envmap import Envmap
from .ppr.technique import Ppr
from .raster import Raster
from .raytrace import Raytrace
from .rerender import Rerender
from .ssr.technique import Ssr
from .virtual import Virtual

TECHNIQUES: dict[str, type[Technique]] = {
    t.name: t for t in (Raytrace, Raster, Rerender, Envmap, Dprm, Virtual, Ssr, Ppr)
}
PARAMS: dict[str, type[BaseModel]] = {name: t.Params for name, t in TECHNIQUES.items()}

TechniqueConfig = Annotated[Union[tuple(PARAMS.values())], Field(discriminator="name")]  # noqa: UP007


def default_technique() -> BaseModel:
    """A scene that names no technique renders with the ray tracer."""
    return Raytrace.Params()
