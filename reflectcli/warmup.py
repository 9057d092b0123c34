"""A tiny scene that touches every kernel once, so compile time is measured apart from frames;
and the notice that says so when that takes a while."""

from __future__ import annotations

import contextlib
import logging
import os
import threading
from collections.abc import Iterator

from .camera import Camera, camera_from_config
from .config.scene import SceneConfig
from .scene.build import build_scene
from .scene.types import Scene

WARM_SCENE = {
    "scene": {"name": "warm-up", "shading": "lambert", "ambient": 0.1},
    "camera": {"eye": [0.0, 1.0, 3.0], "target": [0.0, 1.0, 0.0], "width": 16, "height": 12},
    "materials": {
        "checker": {"kind": "checker"},
        "red": {"kind": "solid", "color": [0.8, 0.1, 0.1]},
    },
    "lights": [{"kind": "point", "position": [0.0, 3.0, 2.0]},
               {"kind": "directional", "direction": [0.0, -1.0, -1.0]}],
    "objects": [
        {"name": "room", "shape": "room", "min": [-4, 0, -4], "max": [4, 4, 4],
         "material": "checker"},
        {"name": "box", "shape": "box", "min": [-0.3, 0, -0.3], "max": [0.3, 0.6, 0.3],
         "material": "red"},
    ],
    "mirrors": [
        {"name": "wall", "shape": "quad", "reflectance": 0.9,
         "corners": [[-2, 0.5, -3.9], [2, 0.5, -3.9], [2, 3, -3.9], [-2, 3, -3.9]]},
        {"name": "ball", "shape": "sphere", "center": [1.5, 1, -1], "radius": 0.5,
         "segments": 8},
        {"name": "tube", "shape": "cylinder", "origin": [-1.5, 0, -1], "radius": 0.3,
         "height": 1, "segments": 8},
        # a concave mesh reflector (explosion maps, refinement, tiles) and an extrusion
        # (the profile search): their kernels compile here, not in a render's first frame
        {"name": "dish", "shape": "cap", "center": [0.7, 1.8, -0.4], "radius": 0.6,
         "axis": [0.0, 0.0, -1.0], "angle": 30.0, "concave": True, "segments": 12},
        {"name": "screen", "shape": "extrusion", "height": 0.4,
         "profile": [[0.3, 0.0], [0.0, 0.05], [-0.3, 0.0]],
         "transform": {"translate": [-0.7, 1.6, -1.0]}},
    ],
}


def warm_scene() -> tuple[Scene, Camera]:
    cfg = SceneConfig.model_validate(WARM_SCENE)
    return build_scene(cfg, "<warm-up>"), camera_from_config(cfg.camera, 0)


def warm_params(params_json: str) -> str:
    """The technique's parameters for the warm-up scene: entries that name the real scene's
    mirrors (envmap `capture`) cannot apply to the warm-up scene's and are left out."""
    import json

    data = json.loads(params_json)
    if isinstance(data.get("capture"), dict):
        data["capture"] = {}
    return json.dumps(data)


COMPILE_NOTICE_SECONDS = 3.0
NO_NOTICE = "REFLECT_NO_COMPILE_NOTICE"  # set (tests/conftest.py): no notice at all
# Its own logger with its own level: while the kernels compile, the warm-up (its scene's
# notices) and the bench (per-job technique notices) set "reflect" to ERROR, and a child
# logger left at NOTSET would inherit that. Records still reach "reflect"'s handler (main()).
notice_log = logging.getLogger("reflect.compile")
notice_log.setLevel(logging.INFO)


@contextlib.contextmanager
def compile_notice(technique: str) -> Iterator[None]:
    """One line on stderr (through main()'s handler) if the body is still compiling after
    COMPILE_NOTICE_SECONDS: a cold compile takes minutes (README), a cached one less than a
    second, so no duration is promised."""
    if os.environ.get(NO_NOTICE):
        yield
        return
    timer = threading.Timer(COMPILE_NOTICE_SECONDS, notice_log.info, (
        f"compiling the numba kernels of '{technique}' (once per install; this can take "
        "minutes; later runs load them from numba's cache)",))
    timer.daemon = True
    timer.start()
    try:
        yield
    finally:
        timer.cancel()
