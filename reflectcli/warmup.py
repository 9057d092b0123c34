"""A tiny scene that touches every kernel once, so compile time is measured apart from frames;
and the notice that says so when that takes a while."""

from __future__ import annotations

import contextlib
import json
import logging
import os
import threading
from collections.abc import Iterator
from pathlib import Path

from .camera import Camera, camera_from_config
from .config.scene import SceneConfig
from .scene.build import build_scene
from .scene.types import Scene

WAVE_PATH = Path(__file__).resolve().parent / "data" / "warm-up-wave.ply"

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
        # a reflector of a concave and a convex part (scripts/make_warm_wave.py): the
        # kernels that draw several parts' passes together compile here too
        {"name": "wave", "shape": "mesh", "path": str(WAVE_PATH),
         "transform": {"scale": 0.45, "rotate": [0.0, 20.0, 0.0],
                       "translate": [-1.3, 1.95, 0.6]}},
    ],
}


def warm_scene() -> tuple[Scene, Camera]:
    cfg = SceneConfig.model_validate(WARM_SCENE)
    return build_scene(cfg, "<warm-up>"), camera_from_config(cfg.camera, 0)


# Map sides on the warm-up scene: the kernels compile for the maps' types, never their
# sizes, so a few texels compile the same code as the scene's resolution (at 1024 texels and
# 8 layers, a distmap warm-up held 6 GiB of maps for its five mirrors: config/memory.py)
WARM_MAP_SIDE = 16
WARM_MAPS = 4  # dprm maps a mirror (a square, for the grid layout)


def warm_params(params_json: str) -> str:
    """The technique's parameters for the warm-up scene: entries that name the real scene's
    mirrors (envmap `capture`) cannot apply to the warm-up scene's and are left out, and maps
    are made small (`WARM_MAP_SIDE`, at most `WARM_MAPS` dprm maps a mirror)."""
    data = json.loads(params_json)
    if isinstance(data.get("capture"), dict):
        data["capture"] = {}
    for holder in (data, data.get("maps"), data.get("explosion")):
        if isinstance(holder, dict) and isinstance(holder.get("resolution"), int):
            holder["resolution"] = min(holder["resolution"], WARM_MAP_SIDE)
    maps = data.get("maps")
    if isinstance(maps, dict) and isinstance(maps.get("count"), int):
        maps["count"] = min(maps["count"], WARM_MAPS)  # a square stays a square
        if isinstance(maps.get("per_frame"), int):
            maps["per_frame"] = min(maps["per_frame"], maps["count"])
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
