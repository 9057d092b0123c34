"""What every technique provides: a Params model and prepare/render."""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Any, ClassVar

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

    def prepare_first_view(self, state: Any, camera: Camera) -> None:
        """One-time work that needs the camera of the path's first frame, done after
        `prepare` and timed with it (the virtual technique's tessellations, which depend
        on the closed pieces the eye is inside). Default: none."""

    def render(self, state: Any, frame_index: int, camera: Camera) -> Frame:
        raise NotImplementedError

    def forget_view(self, state: Any) -> None:
        """Drop what the state caches per camera view, so that rendering the same frame
        again (the bench's repeats of a still scene) costs what a new view costs. Caches of
        the scene (shapes, tessellations, maps) stay: they are one-time work."""


@dataclass
class MapRecord:
    """What precompute reports for each captured (or cached) map or set of maps."""

    mirror: str  # the mirror's name
    status: str  # "captured" or "cached"
    seconds: float
    path: str | None  # the cache file; None when maps are kept in memory only


class MapTechnique(Technique):
    """A technique that captures maps before rendering (`reflect precompute-maps`)."""

    def precompute(self, scene: Scene, on_map=None, on_progress=None) -> list[MapRecord]:
        """Capture (or load from the cache) the scene's maps; one record per mirror.
        on_map(record) after each, on_progress(done, total) as captures proceed."""
        raise NotImplementedError


def warn_non_planar(scene: Scene, technique: str) -> None:
    """Planar-only techniques say which mirrors they leave at their base color."""
    from ..scene.types import PLANAR

    curved = [name for name, kind in zip(scene.mirrors.names, scene.mirrors.kind, strict=True)
              if kind != PLANAR]
    if curved:
        log.warning("%s: reflects planar mirrors only; %s show(s) (1 - r) * base",
                    technique, ", ".join(curved))


def precompute_logged(technique: MapTechnique, scene: Scene,
                      label: str) -> tuple[list[MapRecord], float]:
    """Run a map technique's precompute, say what was captured (only when maps are kept on
    disk: a render without a cache captures everything, and that is no news) and time it."""
    start = time.perf_counter()
    records = technique.precompute(scene)
    # distmap's records are still dicts (issue 16 merge, WIP); read both forms
    fields = [(r["mirror"], r["status"]) if isinstance(r, dict) else (r.mirror, r.status)
              for r in records]
    captured = [mirror for mirror, status in fields if status == "captured"]
    if captured and technique.cache_dir is not None:
        log.info("%s: captured maps of %s; cached %d", label, ", ".join(captured),
                 len(records) - len(captured))
    return records, time.perf_counter() - start


def warn_stale(scene: Scene, technique: str, update="once") -> None:
    """Map techniques captured once say that objects moving later are missing from them."""
    if update == "once" and scene.frame_count > 1 and scene.geometry(0).key[1]:
        log.warning("%s: objects move in this scene, but its maps are captured at frame 0 "
                    "(update = \"once\"): reflections show them where they were then",
                    technique)
