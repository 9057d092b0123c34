"""The technique registry: names -> Params models (eager and light) and technique classes
(imported lazily, with their kernels, only when a technique is used).

Each technique is a package `reflectcli/techniques/<name>/`: its `__init__` holds the
docstring parameter table and `Params` (whose `name` literal is the discriminator, so
`[technique]` in a scene validates against that technique's own fields); its `technique.py`
holds the class. Importing this module loads pydantic models only, no numba.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping
from functools import cache
from typing import TYPE_CHECKING

from pydantic import BaseModel

from . import distmap, dprm, envmap, ppr, raster, raytrace, rerender, ssr, virtual

if TYPE_CHECKING:
    from .base import Technique

DEFAULT_TECHNIQUE = "raytrace"  # a scene that names no technique renders with the ray tracer

_PACKAGES = (raytrace, raster, rerender, envmap, dprm, virtual, distmap, ssr, ppr)
PARAMS: dict[str, type[BaseModel]] = {
    p.__name__.rsplit(".", 1)[1]: p.Params for p in _PACKAGES
}
CLASSES: dict[str, str] = {
    "raytrace": "reflectcli.techniques.raytrace.technique:Raytrace",
    "raster": "reflectcli.techniques.raster.technique:Raster",
    "rerender": "reflectcli.techniques.rerender.technique:Rerender",
    "envmap": "reflectcli.techniques.envmap.technique:Envmap",
    "dprm": "reflectcli.techniques.dprm.technique:Dprm",
    "virtual": "reflectcli.techniques.virtual.technique:Virtual",
    "distmap": "reflectcli.techniques.distmap.technique:Distmap",
    "ssr": "reflectcli.techniques.ssr.technique:Ssr",
    "ppr": "reflectcli.techniques.ppr.technique:Ppr",
}


def technique_class(name: str) -> type[Technique]:
    """The technique class of a registered name (its module and kernels imported now)."""
    module, _, attr = CLASSES[name].partition(":")
    return getattr(importlib.import_module(module), attr)


def technique_doc(name: str) -> str:
    """The technique package's docstring (summary, parameter table, method)."""
    return importlib.import_module(f"reflectcli.techniques.{name}").__doc__ or ""


class _Classes(Mapping):
    """name -> technique class, importing each class on first use."""

    def __getitem__(self, name: str) -> type[Technique]:
        if name not in CLASSES:
            raise KeyError(name)
        return technique_class(name)

    def __iter__(self) -> Iterator[str]:
        return iter(CLASSES)

    def __len__(self) -> int:
        return len(CLASSES)


TECHNIQUES: Mapping[str, type[Technique]] = _Classes()


def default_technique() -> BaseModel:
    """A scene that names no technique renders with the ray tracer."""
    return PARAMS[DEFAULT_TECHNIQUE]()


@cache
def scene_model() -> type[BaseModel]:
    """The scene file's model: config's SceneConfig with `technique` the union of every
    registered technique's Params (config/ itself knows no technique)."""
    from ..config.scene import scene_model_with

    return scene_model_with(PARAMS, DEFAULT_TECHNIQUE)
