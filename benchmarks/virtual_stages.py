"""Where a virtual frame's time goes at each thread count: the wall time of each parallel
kernel (and the serial ones between them) of four-spheres' frame, frames at 1 and 2 threads
alternating in one process, medians.

    .venv/bin/python benchmarks/virtual_stages.py [--scene four-spheres] [--repeats 40]
        [--threads 1,2] [--cold]

Each kernel is timed at its Python call (numba's dispatch included); `frame - sum` is the
Python between them. Take 2-thread figures under the hold tool (/tmp/quiet).
`--cold`: a raytrace frame before each virtual frame, as `benchmarks/virtual.py` alternates
them (its BVH and buffers leave the caches cold for the virtual frame's data).
"""

from __future__ import annotations

import argparse
import collections
import statistics
import time
from pathlib import Path

import numba

import reflectcli.raster.rasterize.passes as passes
import reflectcli.virtual.circle as circle
import reflectcli.virtual.primary as primary
import reflectcli.virtual.together as together
from reflectcli import api

ROOT = Path(__file__).resolve().parents[1]
# (module, function, label): the frame's kernels in the order they run
KERNELS = ((primary, "_draw", "primary draw"),
           (primary, "_primary_rows", "primary merge+shade"),
           (circle, "_blocks", "sphere searches"),
           (together, "pass_labels", "labels (some unseen)"),
           (passes, "_draw_passes", "virtual gather+draw"),
           (together, "_shade_compose", "virtual merge+shade+blend"))


def timer(f, label: str, seconds: dict):
    """f, adding the wall time of each call to seconds[label]."""
    def wrapper(*args, **kw):
        t = time.perf_counter()
        out = f(*args, **kw)
        seconds[label] += time.perf_counter() - t
        return out
    return wrapper


def timed(seconds: dict) -> None:
    """Wraps each kernel so that its calls add their wall time to seconds[label]."""
    for module, name, label in KERNELS:
        setattr(module, name, timer(getattr(module, name), label, seconds))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="four-spheres")
    ap.add_argument("--repeats", type=int, default=40)
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--cold", action="store_true")
    args = ap.parse_args()
    counts = [min(int(t), numba.config.NUMBA_NUM_THREADS) for t in args.threads.split(",")]
    seconds: dict = collections.defaultdict(float)
    timed(seconds)
    o = api.open_scene(str(ROOT / "scenes" / f"{args.scene}.toml"), technique="virtual",
                       threads=max(counts), cache=False)
    o.prepare()
    between = None
    if args.cold:
        between = api.open_scene(str(ROOT / "scenes" / f"{args.scene}.toml"),
                                 technique="raytrace", threads=max(counts), cache=False)
        between.prepare()
    runs = {t: collections.defaultdict(list) for t in counts}
    for rep in range(args.repeats + 2):  # two rounds warm up
        for threads in counts:
            numba.set_num_threads(threads)
            if between is not None:
                between.render_frame(0)
            o.technique.forget_view(o.prepare())
            seconds.clear()
            t = time.perf_counter()
            frame = o.render_frame(0)
            seconds["frame"] = time.perf_counter() - t
            del frame
            if rep >= 2:
                for label in ["frame"] + [k[2] for k in KERNELS]:
                    runs[threads][label].append(seconds.get(label, 0.0))
    print(f"{args.scene}: ms, medians of {args.repeats} frames"
          + (" (each after a raytrace frame)" if args.cold else "") + "; " + ", ".join(
        f"{t} thread(s)" for t in counts) + (", speedup" if len(counts) == 2 else ""))
    labels = [k[2] for k in KERNELS]
    for label in ["frame"] + labels + ["frame - sum"]:
        if label == "frame - sum":
            ms = [1e3 * (statistics.median(runs[t]["frame"])
                         - sum(statistics.median(runs[t][k]) for k in labels)) for t in counts]
        else:
            ms = [1e3 * statistics.median(runs[t][label]) for t in counts]
        ratio = f" {ms[0] / ms[1]:6.2f}x" if len(ms) == 2 and ms[1] > 0 else ""
        print(f"  {label:26s}" + "".join(f" {v:7.3f}" for v in ms) + ratio)


if __name__ == "__main__":
    main()
