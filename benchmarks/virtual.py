"""virtual's frame time against raytrace at 512x512, and its split between tessellation,
map building, virtual vertices and rasterization.

    .venv/bin/python benchmarks/virtual.py [--repeats 9] [--threads 2] [--scenes four-spheres,mask]
        [--floor] [--cpu]

Frames of the two techniques alternate (one of each per round, after a warm-up round), so a
busy machine slows both alike; medians per frame, with the ratio of the minima beside (the
frames least disturbed). The one-time work of each technique (prepare: tessellation,
reflector shapes, Embree scenes) is done before timing. Repeats of a still frame drop
virtual's per-view caches (hidden maps, ray grids, tiles: `Technique.forget_view`), as
`reflect bench` does, so each frame costs what a frame with a new view costs.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numba
import numpy as np

from reflectcli import api

ROOT = Path(__file__).resolve().parents[1]
SPLIT = ("rasterize", "shade", "tessellate", "maps", "virtual_vertices", "virtual_raster",
         "glue")


def opened(scene: str, technique: str, overrides: list[str], threads: int):
    o = api.open_scene(str(ROOT / "scenes" / f"{scene}.toml"), technique=technique,
                       overrides=overrides, threads=threads, cache=False)
    o.prepare()
    return o


def alternate(runs: dict, repeats: int, clock=time.perf_counter) -> dict:
    """name -> list of (seconds, frame); each round renders frame 0 once per technique."""
    out = {k: [] for k in runs}
    for rep in range(repeats + 1):
        for name, o in runs.items():
            o.technique.forget_view(o.prepare())
            t = clock()
            f = o.render_frame(0)
            if rep:  # round 0 warms up
                out[name].append((clock() - t, f))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--scenes", default="four-spheres,mask")
    ap.add_argument("--floor", action="store_true",
                    help="also alternate the raster technique: the primary pass (and the "
                    "mirrors' base colour) that every virtual frame starts with, as a "
                    "ratio of raytrace's frame")
    ap.add_argument("--cpu", action="store_true",
                    help="frame times as the process's CPU time (with --threads 1: what the "
                    "frame costs, whatever else the machine runs; the split stays wall time)")
    args = ap.parse_args()
    numba.set_num_threads(min(args.threads, numba.config.NUMBA_NUM_THREADS))
    for scene in args.scenes.split(","):
        techniques = {"raytrace": opened(scene, "raytrace", ["technique.max_depth=1"],
                                         args.threads),
                      "virtual": opened(scene, "virtual", [], args.threads)}
        if args.floor:
            techniques["raster"] = opened(scene, "raster", [], args.threads)
        runs = alternate(techniques, args.repeats,
                         time.process_time if args.cpu else time.perf_counter)
        ref = np.array([t for t, _ in runs["raytrace"]])
        mine = np.array([t for t, _ in runs["virtual"]])
        split = {k: 1e3 * statistics.median(f.timings.get(k, 0.0) for _, f in runs["virtual"])
                 for k in SPLIT}
        print(f"{scene}: virtual {1e3 * np.median(mine):.0f} ms, raytrace (max_depth 1) "
              f"{1e3 * np.median(ref):.0f} ms, ratio {np.median(mine) / np.median(ref):.2f} "
              f"(minima {mine.min() / ref.min():.2f}); split (ms): "
              + ", ".join(f"{k} {v:.1f}" for k, v in split.items()), flush=True)
        if args.floor:
            first = np.array([t for t, _ in runs["raster"]])
            print(f"{scene}: raster (the primary pass alone) {1e3 * np.median(first):.1f} ms, "
                  f"{np.median(first) / np.median(ref):.2f} of raytrace's frame (minima "
                  f"{first.min() / ref.min():.2f})", flush=True)


if __name__ == "__main__":
    main()
