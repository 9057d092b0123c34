"""Measure technique parameters on the bundled scenes: mirror PSNR against raytrace
(max_depth 1), averaged over frames, unlit and lit; the numbers behind the defaults
(configs/bench/defaults.toml runs the same sweep through `reflect bench`).

    .venv/bin/python scripts/sweep_defaults.py dprm [--width 320] [--frames 0,16,32]
"""

from __future__ import annotations

import argparse
import itertools
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "techniques"))
os.environ["REFLECT_MATRIX_PRINT"] = "1"
import test_matrix as tm  # noqa: E402

from reflectcli import api  # noqa: E402

SWEEPS = {
    "dprm": {
        "technique.maps.count": [1, 16],
        "technique.maps.per_frame": [1, 2],
        "technique.fill.splat": [1, 3],
        "technique.reconstruct": ['"color"', '"surface"'],
    },
    "dprm-native": {
        "technique.maps.count": [16],
        "technique.maps.per_frame": [2, 4],
        "technique.fill.splat": [1, 3],
        "technique.reconstruct": ['"color"', '"surface"'],
    },
    "envmap": {"technique.parallax": ['"none"', '"box"'], "technique.resolution": [256, 512]},
    "distmap": {"technique.layers": [1, 2, 4], "technique.steps": [16, 32]},
    "virtual": {"technique.tessellation.subdivisions": [4, 7, 10]},
}


def _variant(scene: str, lighting: str, width: int):
    path, overrides = tm.variant(scene, lighting)
    overrides = tuple(o for o in overrides if not o.startswith("camera."))
    cam = api.open_scene(path, overrides=list(overrides), cache=False).camera(0)
    if width == 0:
        return path, overrides
    size = (f"camera.width={width}", f"camera.height={round(width * cam.height / cam.width)}")
    return path, overrides + size


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("technique")
    ap.add_argument("--width", type=int, default=320, help="0: the scene's own")
    ap.add_argument("--frames", default="0,16,32")
    ap.add_argument("--scenes", default="")
    args = ap.parse_args()
    sweep = SWEEPS[args.technique]
    technique = args.technique.split("-")[0]
    scenes = [s for s in args.scenes.split(",") if s] or [
        s for s in tm.bundled_scenes() if tm.supports(technique, s)]
    keys = list(sweep)
    print("| scene | lighting | " + " | ".join(k.split(".", 1)[1] for k in keys)
          + " | mean dB | s/frame |")
    print("|---" * (len(keys) + 4) + "|")
    for scene in scenes:
        for lighting in ("unlit", "lit"):
            path, overrides = _variant(scene, lighting, args.width)
            count = api.open_scene(path, overrides=list(overrides), cache=False).frame_count
            frames = [f for f in (int(x) for x in args.frames.split(",")) if f < count]
            refs = {f: api.open_scene(path, overrides=[*overrides, "technique.max_depth=1"],
                                      technique="raytrace", cache=False).render_frame(f)
                    for f in frames}
            for values in itertools.product(*(sweep[k] for k in keys)):
                if args.technique == "dprm" and values[0] == 1 and values[1] > 1:
                    continue
                sets = [f"{k}={v}" for k, v in zip(keys, values, strict=True)]
                opened = api.open_scene(path, overrides=[*overrides, *sets],
                                        technique=technique, cache=False)
                opened.prepare()
                dbs, seconds = [], 0.0
                for f in frames:
                    start = time.perf_counter()
                    out = opened.render_frame(f)
                    seconds += time.perf_counter() - start
                    ref = refs[f]
                    m = ref.mirror_mask & out.mirror_mask
                    mse = float(np.mean((ref.rgb[m].astype(np.float64) - out.rgb[m]) ** 2))
                    dbs.append(math.inf if mse == 0 else -10 * math.log10(mse))
                print(f"| {scene} | {lighting} | " + " | ".join(str(v).strip('"')
                                                               for v in values)
                      + f" | {np.mean(dbs):.2f} | {seconds / len(frames):.3f} |", flush=True)


if __name__ == "__main__":
    main()
