"""reflect's hot paths against the speed anchors, as ratios measured in one run.

    .venv/bin/python benchmarks/anchors.py [--reps 15]
        [--rows warp,raster,rerender,raytrace,mitsuba] [--anchors ../shared/anchors]
        [--gl-python /path/to/python-with-moderngl] [--mitsuba-python /path/to/python]

The anchors (tuned warp, tuned rasterizer, OpenGL llvmpipe stencil mirror; see their README)
are read from `../shared/anchors/` beside the repository when present; without them each row
prints reflect's own time only. Where an anchor runs in this process it is timed round-robin
with reflect's kernel on the same inputs (one call of each per round, medians after warm-up,
p25-p75 in brackets), so a busy machine slows both alike and the ratio stays meaningful.
The OpenGL peer needs moderngl, numpy and trimesh (its own venv; `--gl-python`), runs in a
subprocess before and after reflect's frames, and its two medians are averaged. One venv
serves both peers: `python3 -m venv /tmp/peer && /tmp/peer/bin/pip install moderngl numpy
trimesh mitsuba` (Mitsuba's note: benchmarks/mitsuba.py).

Rows (the table of issue 13):
- warp: the anchor's 512x512 map and camera ("side" motion, whole screen) through reflect's
  warp (projection + splat, its visibility rule) with each pixel's colour (written by the
  warp, as dprm asks for it; and the fill and blend of the dprm stage), against the anchor's
  final kernel, splat 1 and 3. With `--threads 1` it times CPU time (time.thread_time), not
  wall time: a shared machine's waits for a core then stay out of both.
- raster: the anchor's room + icospheres (202,560 / 1,000,960 triangles) through reflect's
  rasterizer (z + id + barycentrics), back faces culled, not culled, and as the primary
  pass draws them (the closed icospheres' back faces culled, the room's walls both ways:
  raster/closed.py), against the anchor's sort-last kernel (culled). The unculled rows are
  also set against the anchor given every triangle twice, in both windings: it then draws
  every triangle once whichever way it faces, the work an unculled rasterizer does (and
  culls the copy).
- rerender: a music-room frame with ~200k triangles (max_depth 1) against the OpenGL
  stencil mirror at 200k triangles (frame + readback).
- raytrace: frames of teapot-box / music-room at 1 spp (rays per second) against raw Embree
  primary rays on the same triangles through embreex, two threads.
- mitsuba: a teapot-box frame (640x480, 1 spp, max_depth 4) against Mitsuba 3's LLVM variant
  on the same triangles and camera (benchmarks/mitsuba.py; Mitsuba in its own venv:
  `--mitsuba-python`, else the row says it skipped); and like for like, reflect's Embree
  scenes built as Mitsuba builds its own (raytrace's `embree = "fast"`: no robust flag,
  high build quality; reflect's own renders keep the robust scenes).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numba
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_ANCHORS = ROOT.parent / "shared" / "anchors"
TABLE: list[tuple[str, str, str, str]] = []  # (row, anchor, reflect, ratio)


def load_anchor(folder: Path, name: str):
    """The anchor script, imported from a copy under the user's cache folder: numba caches
    its kernels beside the copy, never in the (shared, maybe read-only) anchors folder, and
    under the script's own module name (its cache finds the kernels again only by it)."""
    source = folder / f"{name}.py"
    if not source.exists():
        return None
    copy_dir = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "reflect-anchors"
    copy_dir.mkdir(parents=True, exist_ok=True)
    copy = copy_dir / source.name
    if not copy.exists() or copy.read_bytes() != source.read_bytes():
        shutil.copyfile(source, copy)
    if str(copy_dir) not in sys.path:
        sys.path.insert(0, str(copy_dir))
    try:
        return importlib.import_module(name)
    except Exception as exc:  # noqa: BLE001 - an anchor that does not run is reported, skipped
        print(f"  anchor {name} does not load: {exc!r}")
        return None


def _threading_layer() -> str:
    """numba's threading layer, once a parallel loop has run (else 'unknown')."""
    try:
        return numba.threading_layer()
    except ValueError:
        return "unknown"


def round_robin(fns: dict, reps: int, warm: int = 2,
                clock=time.perf_counter) -> dict[str, np.ndarray]:
    """name -> seconds per call; each round calls every function once. `clock`:
    time.thread_time counts only this thread's CPU time, which is all of a numba kernel's
    work at one thread (its parallel loops run on the calling thread) and none of the
    waits while other processes hold the cores."""
    for _ in range(warm):
        for fn in fns.values():
            fn()
    times = {k: [] for k in fns}
    for _ in range(reps):
        for k, fn in fns.items():
            t = clock()
            fn()
            times[k].append(clock() - t)
    return {k: np.array(v) for k, v in times.items()}


def ms(t: np.ndarray) -> str:
    p25, p50, p75 = np.percentile(t * 1e3, [25, 50, 75])
    return f"{p50:.2f} ms [{p25:.2f}-{p75:.2f}]"


def ratio(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """(ratio of medians, ratio of minima): on a machine shared with other work the minima
    are the calls least disturbed by it."""
    return float(np.median(a) / np.median(b)), float(a.min() / b.min())


def add(row: str, anchor: str, mine: str, r, goal: str) -> None:
    if r is None:
        text = "-"
    elif isinstance(r, tuple):
        text = f"{r[0]:.2f}x (minima {r[1]:.2f}x; goal {goal})"
    else:
        text = f"{r:.2f}x (goal {goal})"
    TABLE.append((row, anchor, mine, text))
    print(f"  {row}: reflect {mine} | anchor {anchor} | ratio {text}", flush=True)


# ------------------------------------------------------------------------------ warp
def bench_warp(anchors: Path, reps: int) -> None:
    from reflectcli.maps.warp import WarpBuffers, fill_blend, warp_depths

    print("warp: one 512x512 map into 640x480", flush=True)
    aw = load_anchor(anchors, "warp_tuned")
    h, w = 480, 640
    if aw is not None:
        rgbd = aw.make_map(0)
        cams = aw.Cams(*aw.MOTIONS["side"])
        w_map = np.asarray(cams.M, np.float64)  # (u, v, 1, 1/z) -> clip, as reflect's W
        near = aw.NEAR
    else:  # a plane facing the camera, with reflect's own conventions
        rng = np.random.default_rng(0)
        rgbd = np.concatenate([rng.random((512, 512, 3), dtype=np.float32),
                               np.full((512, 512, 1), 4.0, np.float32)], -1)
        from reflectcli.camera import Camera
        from reflectcli.maps.warp import pixel_to_eye
        cam = Camera(np.zeros(3), np.array([0, 0, -1.0]), np.array([0, 1.0, 0]), 60.0, w, h,
                     0.1, 100.0)
        w_map = cam.projection_matrix() @ pixel_to_eye(
            Camera(np.zeros(3), np.array([0, 0, -1.0]), np.array([0, 1.0, 0]), 60.0, 512, 512,
                   0.1, 100.0))
        near = 0.1
    depth = np.ascontiguousarray(rgbd[..., 3])
    colors = np.ascontiguousarray(rgbd[..., :3]).reshape(-1, 3)
    stencil = np.ones((h, w), bool)
    box = (0, w, 0, h)
    buffers = WarpBuffers(h, w)
    reflected = np.zeros((h, w, 3), np.float32)
    rgb = np.zeros((h, w, 3), np.float32)
    holes = np.zeros((h, w), np.float32)
    background = np.zeros(3, np.float32)
    reflectance = np.full(3, 0.9, np.float32)
    none3, none2 = np.empty((0, 0, 3), np.float32), np.empty((0, 0), bool)
    copy_src = rgbd.copy()
    copy_dst = np.empty_like(copy_src)

    def stage(splat, fill):
        def run():
            # the colour comes with the warp (each zexel that takes a pixel writes its own)
            _, best_id, _, _ = warp_depths([(depth, w_map, None)], near, stencil, splat, False,
                                           buffers, box, [colors], reflected)
            if fill:
                fill_blend(stencil, best_id, reflected, False, none3, none2, False, none3,
                           none2, background, reflectance, rgb, holes)
        return run

    for splat in (1, 3):
        fns = {"reflect": stage(splat, False), "reflect+fill": stage(splat, True),
               "copy": lambda: np.copyto(copy_dst, copy_src)}
        if aw is not None:
            b = aw.Bufs()
            col4 = np.ascontiguousarray(np.concatenate(
                [rgbd.reshape(-1, 4), np.array([[0, 0, 0, np.inf]], np.float32)])).reshape(-1)
            a_, e_, cst, _ = cams.f32()
            s = 0 if splat == 1 else 1
            fns["anchor"] = (lambda s=s, b=b, a_=a_, e_=e_, cst=cst, col4=col4: aw.warp_final(
                depth, col4, a_, e_, cst, b.zd, b.cd, b.zt, b.ct, b.pix, b.zmap, b.rlo, b.rhi,
                b.rcnt, s, numba.get_num_threads(), b.vzs, b.vqs))
        # one thread: CPU time, so a shared machine's waits do not enter the ratio
        # (numba's workqueue layer would run parallel loops on a worker thread: wall time)
        one = numba.get_num_threads() == 1 and _threading_layer() != "workqueue"
        t = round_robin(fns, reps, clock=time.thread_time if one else time.perf_counter)
        anchor = ms(t["anchor"]) if "anchor" in t else f"(none; numpy copy {ms(t['copy'])})"
        base = t.get("anchor", t["copy"])
        goal = "<= 1.3" if splat == 1 else "<= 1.5"
        cpu = " (CPU time)" if one else ""
        add(f"warp splat {splat}, colour gathered{cpu}", anchor, ms(t["reflect"]),
            ratio(t["reflect"], base) if "anchor" in t else None, goal)
        add(f"warp splat {splat}, + fill and blend (dprm stage){cpu}", anchor,
            ms(t["reflect+fill"]),
            ratio(t["reflect+fill"], base) if "anchor" in t else None, goal)


# ------------------------------------------------------------------------------ raster
def bench_raster(anchors: Path, reps: int) -> None:
    print("raster: room + icospheres, 640x480, z + id", flush=True)
    ar = load_anchor(anchors, "raster_tuned")
    if ar is None:
        print("  (anchor raster_tuned.py missing: rows skipped, they need its scene)")
        return
    for n_spheres, subdiv in ((625, 2), (780, 3)):
        raster_case(ar, n_spheres, subdiv, reps)


def raster_case(ar, n_spheres: int, subdiv: int, reps: int) -> None:
    from reflectcli.raster.rasterize import (
        CULL_BACK,
        CULL_NONE,
        FLAG_CULL_BACK,
        RasterWorkspace,
        rasterize,
    )

    v, f, m = ar.make_scene(n_spheres, subdiv)
    corners = np.ascontiguousarray(v[f], np.float32)
    flags = np.zeros(len(f), np.uint8)
    m64 = np.asarray(m, np.float64)
    ws = RasterWorkspace()
    nv = len(v)
    x, y, z = (np.empty(nv, np.float32) for _ in range(3))
    zb, ib = np.empty((ar.H, ar.W), np.float32), np.empty((ar.H, ar.W), np.int32)
    zbs, ibs = np.empty((2, ar.W * ar.H), np.float32), np.empty((2, ar.W * ar.H), np.int32)
    both = np.ascontiguousarray(np.concatenate([f, f[:, ::-1]]), f.dtype)  # both windings
    # as reflect's primary pass flags them (raster/closed.py): the icospheres, closed and
    # seen from outside, have their back faces culled; the room's walls are drawn both ways
    walls = len(f) - n_spheres * 20 * 4 ** subdiv
    primary = np.where(np.arange(len(f)) >= walls, FLAG_CULL_BACK, 0).astype(np.uint8)
    fns = {
        "culled": lambda: rasterize(corners, flags, m64, 640, 480, cull=CULL_BACK,
                                    workspace=ws),
        "unculled": lambda: rasterize(corners, flags, m64, 640, 480, cull=CULL_NONE,
                                      workspace=ws),
        "primary": lambda: rasterize(corners, primary, m64, 640, 480, cull=CULL_NONE,
                                     workspace=ws),
        "anchor": lambda: ar.tuned_sortlast(v, m, f, x, y, z, zb.reshape(-1),
                                            ib.reshape(-1), zbs, ibs),
        "anchor, both windings": lambda: ar.tuned_sortlast(v, m, both, x, y, z, zb.reshape(-1),
                                                           ib.reshape(-1), zbs, ibs),
    }
    t = round_robin(fns, reps)
    add(f"rasterize {len(f):,} triangles, culled", ms(t["anchor"]), ms(t["culled"]),
        ratio(t["culled"], t["anchor"]), "<= 1.5")
    add(f"rasterize {len(f):,} triangles, unculled", ms(t["anchor"]), ms(t["unculled"]),
        ratio(t["unculled"], t["anchor"]), "<= 1.5")
    add(f"rasterize {len(f):,} triangles, unculled, vs anchor given both windings",
        ms(t["anchor, both windings"]), ms(t["unculled"]),
        ratio(t["unculled"], t["anchor, both windings"]), "(like for like)")
    add(f"rasterize {len(f):,} triangles, as the primary pass (closed spheres culled)",
        ms(t["anchor"]), ms(t["primary"]), ratio(t["primary"], t["anchor"]), "<= 1.5")


# ------------------------------------------------------------------------------ rerender
def gl_peer(anchors: Path, python: str | None, frames: int) -> float | None:
    """Median ms of the OpenGL stencil mirror at 200k triangles, frame + readback."""
    script = anchors / "bench_gl_mirror.py"
    if python is None or not script.exists():
        return None
    env = dict(os.environ, LP_NUM_THREADS="2")
    try:
        out = subprocess.run([python, str(script), "--sizes", "625", "--frames", str(frames),
                              "--warm", "3"], capture_output=True, text=True, env=env,
                             timeout=600, check=True).stdout
    except (OSError, subprocess.SubprocessError) as exc:
        print(f"  OpenGL peer does not run: {exc!r}")
        return None
    for line in out.splitlines():
        row = json.loads(line)
        if row.get("spheres") == 625:
            return float(row["mirror_read"]["med"])
    return None


def bench_rerender(anchors: Path, reps: int, gl_python: str | None) -> None:
    from reflectcli import api

    print("rerender: music-room with ~200k triangles, max_depth 1", flush=True)
    opened = api.open_scene(str(ROOT / "scenes" / "music-room.toml"), technique="rerender",
                            overrides=["objects.furniture.triangles=200000",
                                       "technique.max_depth=1"], threads=2, cache=False)
    opened.prepare()
    tris = opened.scene.geometry(0).all_triangles().count
    before = gl_peer(anchors, gl_python, reps)
    t = round_robin({"frame": lambda: opened.render_frame(0)}, reps)["frame"]
    after = gl_peer(anchors, gl_python, reps)
    gl = [x for x in (before, after) if x is not None]
    if gl:
        add(f"rerender frame, {tris:,} triangles", f"{np.mean(gl):.2f} ms (OpenGL llvmpipe, "
            f"{' / '.join(f'{x:.1f}' for x in gl)})", ms(t), float(np.median(t) * 1e3
                                                                / np.mean(gl)), "<= 0.5")
    else:
        add(f"rerender frame, {tris:,} triangles", "(OpenGL peer not run: --gl-python)", ms(t),
            None, "<= 0.5")


# ------------------------------------------------------------------------------ raytrace
def bench_raytrace(reps: int) -> None:
    print("raytrace: 640x480, 1 spp, against raw Embree primary rays", flush=True)
    pool = ThreadPoolExecutor(2)
    for name in ("teapot-box", "music-room"):
        raytrace_case(name, pool, reps)


def raytrace_case(name: str, pool: ThreadPoolExecutor, reps: int) -> None:
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    from reflectcli import api

    opened = api.open_scene(str(ROOT / "scenes" / f"{name}.toml"), technique="raytrace",
                            threads=2, cache=False)
    opened.prepare()
    camera = opened.camera(0)
    rays = opened.render_frame(0).stats["rays"]
    corners = np.ascontiguousarray(opened.scene.geometry(0).all_triangles().corners,
                                   np.float32)
    embree = rtcore_scene.EmbreeScene()
    TriangleMesh(embree, corners)
    d = camera.pixel_directions(1).reshape(-1, 3).astype(np.float32)
    o = np.ascontiguousarray(np.broadcast_to(camera.eye, d.shape), np.float32)
    halves = [(o[: len(d) // 2], d[: len(d) // 2]), (o[len(d) // 2:], d[len(d) // 2:])]

    def raw():
        list(pool.map(lambda od: embree.run(od[0], od[1], output=1), halves))

    t = round_robin({"frame": lambda: opened.render_frame(0), "embree": raw}, reps)
    mine = rays / np.median(t["frame"]) / 1e6
    peer = len(d) / np.median(t["embree"]) / 1e6
    add(f"raytrace {name} ({rays:,} rays a frame)", f"{peer:.2f} Mrays/s",
        f"{mine:.2f} Mrays/s ({ms(t['frame'])})", mine / peer, ">= 0.5")


# ------------------------------------------------------------------------------ mitsuba
def bench_mitsuba(reps: int, python: str | None, threads: int) -> None:
    print("mitsuba: teapot-box, 640x480, 1 spp, max_depth 4, against Mitsuba 3 llvm_ad_rgb",
          flush=True)
    spec = importlib.util.spec_from_file_location("reflect_bench_mitsuba",
                                                  ROOT / "benchmarks" / "mitsuba.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    # frames alternating one by one, each after an idle gap; then runs of frames back to back
    # (as a batch render runs them; the first of each run, woken from the gap, not counted);
    # then the runs with reflect's Embree scenes built as Mitsuba builds its own (no robust
    # flag, high build quality: raytrace's `embree = "fast"`), like for like
    for run, label, embree in ((1, "frames alternating", "robust"),
                               (6, "runs of 6 frames", "robust"),
                               (6, "runs of 6 frames, reflect's Embree scenes as Mitsuba "
                                   "builds its own (embree = \"fast\")", "fast")):
        r = module.compare("teapot-box", python, reps if run == 1 else max(2, reps // 3),
                           threads, "llvm_ad_rgb", run=run, embree=embree)
        if r is None:
            add("raytrace frame vs Mitsuba 3 (teapot-box)", "(skipped: no --mitsuba-python)",
                "-", None, "<= 1")
            return
        add(f"raytrace frame vs Mitsuba 3 (teapot-box, {r['rays']:,} rays), {label}",
            f"{ms(r['mitsuba'])} ({r['version']['variant']}; first frame "
            f"{1e3 * r['mitsuba_first']:.0f} ms)", ms(r["reflect"]),
            ratio(r["reflect"], r["mitsuba"]), "<= 1")
        add(f"raytrace frame vs Mitsuba 3, CPU time (all threads of each process), {label}",
            f"{ms(r['mitsuba_cpu'])}", ms(r["reflect_cpu"]),
            ratio(r["reflect_cpu"], r["mitsuba_cpu"]), "<= 1")
        print(f"    CPU of the other side during a frame (median): Mitsuba's worker during "
              f"reflect's {1e3 * np.median(r['mitsuba_during_reflect']):.2f} ms, reflect's "
              f"process during Mitsuba's {1e3 * np.median(r['reflect_during_mitsuba']):.2f} "
              f"ms", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--reps", type=int, default=15)
    ap.add_argument("--rows", default="warp,raster,rerender,raytrace,mitsuba")
    ap.add_argument("--threads", type=int, default=2,
                    help="numba threads for reflect and the numba anchors (1 shows the work "
                         "without waits on a busy machine)")
    ap.add_argument("--anchors", type=Path, default=DEFAULT_ANCHORS)
    ap.add_argument("--gl-python", default=os.environ.get("REFLECT_GL_PYTHON"),
                    help="a python with moderngl for the OpenGL peer (default: "
                         "$REFLECT_GL_PYTHON, else this python if it has moderngl)")
    ap.add_argument("--mitsuba-python", default=os.environ.get("REFLECT_MITSUBA_PYTHON"),
                    help="a python with mitsuba for the Mitsuba row (default: "
                         "$REFLECT_MITSUBA_PYTHON; benchmarks/mitsuba.py)")
    args = ap.parse_args()
    if args.gl_python is None and importlib.util.find_spec("moderngl") is not None:
        args.gl_python = sys.executable
    numba.set_num_threads(min(args.threads, numba.config.NUMBA_NUM_THREADS))
    print(f"anchors: {args.anchors} ({'found' if args.anchors.exists() else 'missing'}); "
          f"numba threads {numba.get_num_threads()}; reps {args.reps}")
    rows = args.rows.split(",")
    if "warp" in rows:
        bench_warp(args.anchors, args.reps)
    if "raster" in rows:
        bench_raster(args.anchors, args.reps)
    if "rerender" in rows:
        bench_rerender(args.anchors, args.reps, args.gl_python)
    if "raytrace" in rows:
        bench_raytrace(args.reps)
    if "mitsuba" in rows:
        bench_mitsuba(args.reps, args.mitsuba_python, numba.get_num_threads())
    print("\n| what | anchor | reflect | reflect / anchor (median; minima) |\n|---|---|---|---|")
    for row in TABLE:
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
