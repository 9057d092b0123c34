"""virtual's frame time against raytrace at 512x512, and its split between tessellation,
map building, virtual vertices and rasterization (medians of frames after a warm-up).

    .venv/bin/python benchmarks/virtual.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

from reflectcli import api

ROOT = Path(__file__).resolve().parents[1]


def frames(scene: str, technique: str, overrides: list[str], repeats: int):
    opened = api.open_scene(str(ROOT / "scenes" / f"{scene}.toml"), technique=technique,
                            overrides=overrides, threads=2, cache=False)
    opened.render_frame(0)  # warm-up (and cached tessellation)
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        f = opened.render_frame(0)
        out.append((time.perf_counter() - t, f))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    for scene in ("four-spheres", "mask"):
        ref = statistics.median(t for t, _ in frames(scene, "raytrace",
                                                     ["technique.max_depth=1"], args.repeats))
        runs = frames(scene, "virtual", [], args.repeats)
        total = statistics.median(t for t, _ in runs)
        split = {k: 1e3 * statistics.median(f.timings.get(k, 0.0) for _, f in runs)
                 for k in ("rasterize", "shade", "tessellate", "maps", "virtual_vertices",
                           "virtual_raster")}
        print(f"{scene}: virtual {1e3 * total:.0f} ms, raytrace (max_depth 1) {1e3 * ref:.0f} ms,"
              f" ratio {total / ref:.1f}; split (ms): "
              + ", ".join(f"{k} {v:.1f}" for k, v in split.items()))


if __name__ == "__main__":
    main()
