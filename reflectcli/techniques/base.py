"""What every technique provides: a Params model and prepare/render."""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import BaseModel

from ..camera import Camera
from ..frame import Frame
from ..scene.types import Scene


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


def parameter_table(params: type[BaseModel]) -> list[tuple[str, str, str, str]]:
    """(name, type, default, description) rows from a Params model, for `reflect techniques`."""
    rows = []
    for name, field in params.model_fields.items():
        if name == "name":
            continue
        annotation = getattr(field.annotation, "__name__", None) or str(field.annotation)
        annotation = annotation.replace("typing.", "")
        rows.append((name, annotation, repr(field.default), field.description or ""))
    return rows
