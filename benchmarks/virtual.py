"""virtual's frame time against raytrace at 512x512, and its split between tessellation,
map building, virtual vertices and rasterization.

    .venv/bin/python benchmarks/virtual.py [--repeats 9] [--threads 2] [--scenes four-spheres,mask]
        [--floor] [--cpu] [--raster-anchor [--anchors ../shared/anchors]]

Frames of the two techniques alternate (one of each per round, after a warm-up round), so a
busy machine slows both alike; medians per frame, with the ratio of the minima beside (the
frames least disturbed). The one-time work of each technique (prepare: tessellation,
reflector shapes, Embree scenes) is done before timing. Repeats of a still frame drop
virtual's per-view caches (hidden maps, ray grids, tiles: `Technique.forget_view`), as
`reflect bench` does, so each frame costs what a frame with a new view costs.

`--raster-anchor`: the virtual passes' rasterization alone, in ns a triangle, against the
tuned rasterizer anchor (`raster_tuned.py`) on the same triangles: the passes of a frame are
captured and replayed (as the frame runs them: stencil, depth floor, clip planes; and bare:
the triangles alone), and the anchor draws the same triangles in the same pixels (its
640x480 buffer, each triangle turned to face it: it culls back faces, a virtual pass cannot).
With --threads 1 the times are CPU times (time.thread_time).
"""

from __future__ import annotations

import argparse
import statistics
import sys
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
    """name -> list of (seconds by `clock`, the frame's timings); each round renders frame 0
    once per technique. Frames are dropped as a render drops them once written: kept, each
    new frame's buffers were fresh pages to fault in (about 1,000 a frame at 512x512)."""
    out = {k: [] for k in runs}
    for rep in range(repeats + 1):
        for name, o in runs.items():
            o.technique.forget_view(o.prepare())
            t = clock()
            f = o.render_frame(0)
            seconds = clock() - t
            if rep:  # round 0 warms up
                out[name].append((seconds, f.timings))
            del f
    return out


def captured_passes(scene: str, threads: int) -> list[tuple]:
    """The rasterize calls of a virtual frame's passes: (corners, flags, clip_from_world,
    width, height, planes, mask, depth_floor), copied; passes drawn together
    (`rasterize_passes`: sphere mirrors, and a mesh reflector's explosion parts) as one
    call each."""
    import reflectcli.virtual.partpasses as vp
    import reflectcli.virtual.raster as vr
    import reflectcli.virtual.together as vt
    from reflectcli.raster.rasterize import standard_planes

    calls = []
    real = vr.rasterize
    real_passes = vt.rasterize_passes

    def spy(corners, flags, m, width, height, planes, mask=None, depth_floor=None, **kw):
        calls.append((corners.copy(), flags.copy(), m.copy(), width, height, planes.copy(),
                      None if mask is None else mask.copy(),
                      None if depth_floor is None else depth_floor.copy()))
        return real(corners, flags, m, width, height, planes, mask=mask,
                    depth_floor=depth_floor, **kw)

    def spy_passes(corners, flags, m, width, height, starts, boxes, labels, depth_floor,
                   workspace, **kw):
        out = real_passes(corners, flags, m, width, height, starts, boxes, labels,
                          depth_floor, workspace, **kw)
        for p in range(len(boxes)):  # corners gathered by the call: copied after it
            s, e = starts[p], starts[p + 1]
            y0, y1, x0, x1 = boxes[p]  # labels are set only in the passes' boxes
            mask = np.zeros(labels.shape, np.uint8)
            mask[y0:y1, x0:x1] = labels[y0:y1, x0:x1] == p + 1
            calls.append((corners[s:e].copy(), flags[s:e].copy(), m.copy(), width, height,
                          standard_planes(), mask,
                          None if depth_floor is None else depth_floor.copy()))
        return out

    o = opened(scene, "virtual", [], threads)
    vr.rasterize = spy
    vt.rasterize_passes = vp.rasterize_passes = spy_passes
    try:
        o.render_frame(0)
    finally:
        vr.rasterize = real
        vt.rasterize_passes = vp.rasterize_passes = real_passes
    return calls


def raster_against_anchor(scene: str, threads: int, repeats: int, anchors: Path) -> None:
    """Prints the virtual passes' rasterization in ns a triangle against the tuned anchor's
    on the same triangles (--raster-anchor): whether the passes' cost is the rasterizer's
    or the method's."""
    from reflectcli.raster.rasterize import RasterWorkspace, rasterize, standard_planes

    source = anchors / "raster_tuned.py"
    if not source.exists():
        print(f"{scene}: anchor {source} missing, --raster-anchor skipped")
        return
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from anchors import load_anchor

    ar = load_anchor(anchors, "raster_tuned")
    calls = captured_passes(scene, threads)
    ws = RasterWorkspace(outputs=True)
    anchor_inputs = []
    for corners, flags, m, width, height, _, _, _ in calls:
        keep = (flags & 2) == 0  # FLAG_SKIP: the pass leaves them out
        soup = np.ascontiguousarray(corners[keep].reshape(-1, 3), np.float32)
        # clip space of the anchor's 640x480 buffer putting each triangle on the pixels
        # of the pass's width x height (rows past 480 fall off; the passes' boxes do not)
        fit = np.eye(4)
        fit[0] = [width / ar.W, 0, 0, width / ar.W - 1.0]
        fit[1] = [0, height / ar.H, 0, 1.0 - height / ar.H]
        mm = fit @ m
        clip = np.c_[soup, np.ones(len(soup))] @ mm.T
        xy = clip[:, :2] / clip[:, 3:]
        tri = xy.reshape(-1, 3, 2)
        # the anchor's screen y points down: its front faces have negative signed area there
        area = ((tri[:, 1, 0] - tri[:, 0, 0]) * (tri[:, 2, 1] - tri[:, 0, 1])
                - (tri[:, 2, 0] - tri[:, 0, 0]) * (tri[:, 1, 1] - tri[:, 0, 1]))
        faces = np.arange(len(soup), dtype=np.int32).reshape(-1, 3)
        faces[area < 0] = faces[area < 0][:, ::-1]
        n = len(soup)
        anchor_inputs.append((soup, mm.astype(np.float32), np.ascontiguousarray(faces),
                              *(np.empty(n, np.float32) for _ in range(3))))
    zb = np.empty(ar.W * ar.H, np.float32)
    ib = np.empty(ar.W * ar.H, np.int32)
    zbs = np.empty((2, ar.W * ar.H), np.float32)
    ibs = np.empty((2, ar.W * ar.H), np.int32)
    std = standard_planes()

    def framed():
        for corners, flags, m, width, height, planes, mask, floor in calls:
            rasterize(corners, flags, m, width, height, planes, mask=mask, depth_floor=floor,
                      workspace=ws)

    def bare():
        for corners, flags, m, width, height, _, _, _ in calls:
            rasterize(corners, flags, m, width, height, std, workspace=ws)

    def anchor():
        for v, mm, f, x, y, z in anchor_inputs:
            if threads == 1:
                ar.tuned_serial(v, mm, f, x, y, z, zb, ib)
            else:
                ar.tuned_sortlast(v, mm, f, x, y, z, zb, ib, zbs, ibs)

    empty = (np.zeros((0, 3), np.float32), anchor_inputs[0][1], np.zeros((0, 3), np.int32),
             *(np.empty(0, np.float32) for _ in range(3)))

    def clears():  # the anchor's buffer clears alone (no triangle)
        for _ in anchor_inputs:
            if threads == 1:
                ar.tuned_serial(*empty, zb, ib)
            else:
                ar.tuned_sortlast(*empty, zb, ib, zbs, ibs)

    clock = time.thread_time if threads == 1 else time.perf_counter
    fns = {"framed": framed, "bare": bare, "anchor": anchor, "clears": clears}
    times = {k: [] for k in fns}
    for rep in range(repeats + 2):
        for k, fn in fns.items():
            t = clock()
            fn()
            if rep >= 2:
                times[k].append(clock() - t)
    count = sum(int(np.count_nonzero((c[1] & 2) == 0)) for c in calls)
    ns = {k: 1e9 * statistics.median(v) / count for k, v in times.items()}
    print(f"{scene}: virtual passes' rasterization, {count:,} triangles in {len(calls)} "
          f"passes: {ns['framed']:.1f} ns a triangle as the frame runs them, bare "
          f"{ns['bare']:.1f}, the anchor {ns['anchor']:.1f} ({ns['clears']:.1f} of it its "
          f"640x480 buffer clears): ratio {ns['framed'] / ns['anchor']:.2f} (bare "
          f"{ns['bare'] / ns['anchor']:.2f}; against the anchor's triangles alone "
          f"{ns['framed'] / (ns['anchor'] - ns['clears']):.2f})", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--scenes", default="four-spheres,mask")
    ap.add_argument("--floor", action="store_true",
                    help="also alternate the raster technique: the primary pass (and the "
                    "mirrors' base colour) that every virtual frame starts with, as a "
                    "ratio of raytrace's frame")
    ap.add_argument("--raster-anchor", action="store_true",
                    help="also time the virtual passes' rasterization against the tuned "
                    "rasterizer anchor on the same triangles (ns a triangle)")
    ap.add_argument("--anchors", type=Path, default=ROOT.parent / "shared" / "anchors")
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
        split = {k: 1e3 * statistics.median(timings.get(k, 0.0) for _, timings in runs["virtual"])
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
        if args.raster_anchor:
            raster_against_anchor(scene, args.threads, args.repeats, args.anchors)


if __name__ == "__main__":
    main()
