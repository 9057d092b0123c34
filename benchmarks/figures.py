"""Speed figures for the closing notes: medians after a warm-up, ratios measured in one run.

    .venv/bin/python benchmarks/figures.py [--repeats 7]

Prints: ray tracer throughput (rays/s) against raw Embree primary-ray throughput on the same
scene; Embree build time; rerender and raster frame time against music-room's triangle count
with a linear fit; rerender / raytrace frame-time ratios; a memcpy of a frame's bytes.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from reflectcli import api
from reflectcli.trace.embree import TriangleScene

ROOT = Path(__file__).resolve().parents[1]


def median_time(fn, repeats):
    fn()  # warm-up
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), min(times), max(times)


def setup(scene, technique, overrides=()) -> api.OpenedScene:
    """A shipped scene opened with the technique, prepared (frame times are frames only)."""
    opened = api.open_scene(str(ROOT / "scenes" / f"{scene}.toml"), technique=technique,
                            overrides=list(overrides), threads=2, cache=False)
    opened.prepare()
    return opened


def throughput(scene, repeats):
    opened = setup(scene, "raytrace", ("technique.max_depth=4",))
    camera = opened.camera(0)
    frame = opened.render_frame(0)
    rays = frame.stats["rays"]
    med, lo, hi = median_time(lambda: opened.render_frame(0), repeats)
    tris = opened.scene.geometry(0).all_triangles()
    t = time.perf_counter()
    embree = TriangleScene(tris.corners)
    build = time.perf_counter() - t
    d = camera.pixel_directions(1).reshape(-1, 3).astype(np.float32)
    o = (camera.eye + camera.near * d).astype(np.float32)
    far = np.full(len(d), camera.far, np.float32)
    emed, _, _ = median_time(lambda: embree.intersect(o, d, far, threads=2), repeats)
    print(f"{scene}: {tris.count} triangles; raytrace max_depth 4: {rays} rays in "
          f"{med * 1e3:.1f} ms (min {lo * 1e3:.1f}, max {hi * 1e3:.1f}) = "
          f"{rays / med / 1e6:.2f} Mrays/s; raw Embree primary rays: "
          f"{len(d) / emed / 1e6:.2f} Mrays/s; ratio {rays / med / (len(d) / emed):.2f}; "
          f"Embree build {build * 1e3:.0f} ms")
    return med


def frame_time(scene, technique, repeats, overrides=()):
    opened = setup(scene, technique, overrides)
    med, _, _ = median_time(lambda: opened.render_frame(0), repeats)
    return med, opened.scene.geometry(0).all_triangles().count


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    r = args.repeats
    buf = np.zeros(640 * 480 * 4 * 6, np.uint8)
    cmed, _, _ = median_time(lambda: buf.copy(), r)
    print(f"memcpy of one 640x480 6-channel float frame: {cmed * 1e3:.3f} ms")
    for scene in ("teapot-box", "music-room"):
        throughput(scene, r)
    for scene in ("teapot-box", "music-room"):
        rt, _ = frame_time(scene, "raytrace", r, ("technique.max_depth=1",))
        rr, _ = frame_time(scene, "rerender", r, ("technique.max_depth=1",))
        ra, _ = frame_time(scene, "raster", r)
        print(f"{scene} (max_depth 1): rerender {rr * 1e3:.1f} ms, raytrace {rt * 1e3:.1f} ms, "
              f"raster {ra * 1e3:.1f} ms; rerender/raytrace = {rr / rt:.2f}")
    xs, ys = [], []
    for n in (2_000, 20_000, 200_000, 1_000_000):
        rr, tris = frame_time("music-room", "rerender", r,
                              (f"objects.furniture.triangles={n}", "technique.max_depth=1"))
        rt, _ = frame_time("music-room", "raytrace", max(3, r // 2),
                           (f"objects.furniture.triangles={n}", "technique.max_depth=1"))
        xs.append(tris)
        ys.append(rr)
        print(f"music-room {tris:>8} triangles: rerender {rr * 1e3:7.1f} ms, "
              f"raytrace {rt * 1e3:7.1f} ms")
    slope, intercept = np.polyfit(xs, ys, 1)
    print(f"rerender frame time ~= {intercept * 1e3:.2f} ms + {slope * 1e9:.1f} ns * triangles")


if __name__ == "__main__":
    main()
