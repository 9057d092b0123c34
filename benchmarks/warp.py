"""Warp time of one 512x512 zexel map into 640x480 (teapot-box frame 0), 1 and 2 threads,
splat 1 and 3, beside a numpy copy of the same bytes (the map's color + depth), in one run.

    .venv/bin/python benchmarks/warp.py [--repeats 21]
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numba
import numpy as np

from reflectcli import api
from reflectcli.geometry import reflection_matrix
from reflectcli.maps.warp import warp_maps
from reflectcli.maps.zexel import capture_map, map_camera, mirror_frame
from reflectcli.raster.primary import render_primary

ROOT = Path(__file__).resolve().parents[1]


def median_ms(fn, repeats):
    fn()
    fn()
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return 1e3 * statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=21)
    args = ap.parse_args()
    # the kernels by hand below; the scene and its camera come from the api like any render's
    opened = api.open_scene(str(ROOT / "scenes" / "teapot-box.toml"), technique="dprm",
                            cache=False)
    scene, cam = opened.scene, opened.camera(0)
    mf = mirror_frame(scene, 0)
    n, d = mf.normal, float(-mf.normal @ mf.center)
    zmap = capture_map(scene, 0, map_camera(mf, mf.center - mf.diagonal * n, 512, 0.01, 100.0))
    stencil = render_primary(scene, 0, cam).frame.surface == scene.n_objects
    eye_m = cam.eye - 2 * (n @ cam.eye + d) * n
    reflect = reflection_matrix(n, d)
    data = np.concatenate([zmap.color.reshape(-1), zmap.depth.reshape(-1)])
    copy_ms = median_ms(lambda: data.copy(), args.repeats)
    print(f"numpy copy of the map's {data.nbytes / 2**20:.1f} MiB: {copy_ms:.3f} ms")
    for threads in (1, 2):
        numba.set_num_threads(threads)
        for splat in (1, 3, "adaptive"):
            ms = median_ms(lambda s=splat: warp_maps([zmap], cam, reflect, eye_m, stencil, s,
                                                     False), args.repeats)
            print(f"threads {threads} splat {splat!s:>8}: {ms:6.2f} ms "
                  f"({ms / copy_ms:.1f}x the copy)")
        ms = median_ms(lambda: warp_maps([zmap], cam, reflect, eye_m, stencil, 1, True),
                       args.repeats)
        print(f"threads {threads} ordered splat 1: {ms:6.2f} ms")


if __name__ == "__main__":
    main()
