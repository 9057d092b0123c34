"""What every technique provides: a Params model and prepare/render."""

from __future__ import annotations

import logging
import time
from types import UnionType
from typing import Any, ClassVar, Literal, Union, get_args, get_origin

from pydantic import BaseModel

from ..camera import Camera
from ..frame import Frame
from ..scene.types import Scene

log = logging.getLogger("reflect")


class Technique:
    """A reflection technique. Subclasses set `name` and `Params` and implement both methods.

    `prepare` does the per-scene work (acceleration structures, maps) and returns a state;
    `render` draws one frame from it. Both stay in Python; numba kernels do the work.
    """

    name: ClassVar[str]
    Params: ClassVar[type[BaseModel]]

    def __init__(self, params: BaseModel, threads: int = 1, cache_dir: str | None = None) -> None:
        self.params = params
        self.threads = threads
        self.cache_dir = cache_dir  # where precomputed maps live; None keeps them in memory

    def prepare(self, scene: Scene) -> Any:
        raise NotImplementedError

    def render(self, state: Any, frame: int, camera: Camera) -> Frame:
        raise NotImplementedError


def warn_non_planar(scene: Scene, technique: str) -> None:
    """Planar-only techniques say which mirrors they leave at their base color."""
    from ..scene.types import PLANAR

    curved = [name for name, kind in zip(scene.mirrors.names, scene.mirrors.kind, strict=True)
              if kind != PLANAR]
    if curved:
        log.warning("%s: reflects planar mirrors only; %s show(s) (1 - r) * base",
                    technique, ", ".join(curved))


def precompute_logged(technique, scene: Scene, label: str) -> tuple[list[dict], float]:
    """Run a map technique's precompute, say what was captured (only when maps are kept on
    disk: a render without a cache captures everything, and that is no news) and time it."""
    start = time.perf_counter()
    records = technique.precompute(scene)
    captured = [r["mirror"] for r in records if r["status"] == "captured"]
    if captured and technique.cache_dir is not None:
        log.info("%s: captured maps of %s; cached %d", label, ", ".join(captured),
                 len(records) - len(captured))
    return records, time.perf_counter() - start


def parameter_table(params: type[BaseModel], prefix: str = "") -> list[tuple[str, str, str, str]]:
    """(dotted name, type, default, description) rows from a Params model, nested models
    flattened (`maps.count`), for `reflect techniques`: never a hand-kept list."""
    rows = []
    for name, field in params.model_fields.items():
        if name == "name" and not prefix:
            continue
        annotation = field.annotation
        default = field.get_default(call_default_factory=True)
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            rows += parameter_table(annotation, f"{prefix}{name}.")
            continue
        rows.append((f"{prefix}{name}", type_name(annotation), toml_value(default),
                     field.description or ""))
    return rows


def type_name(annotation) -> str:
    """A readable type: int, float, "a" | "b", xyz, ..."""
    origin = get_origin(annotation)
    args = get_args(annotation)
    if origin is Literal:
        return " | ".join(toml_value(a) for a in args)
    if origin in (Union, UnionType):
        return " | ".join(type_name(a) for a in args if a is not type(None)) + " (optional)"
    if origin is tuple and len(args) == 3 and all(a is float for a in args):
        return "xyz"
    if origin is dict:
        return f"table of {type_name(args[1])}"
    return getattr(annotation, "__name__", str(annotation))


def toml_value(value) -> str:
    """A default as it would be written in TOML."""
    if value is None:
        return "(unset)"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, tuple | list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + "}"
    return str(value)
