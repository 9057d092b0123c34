"""reflect's raytrace frame against Mitsuba 3's LLVM variant on the same triangles, as a ratio.

    .venv/bin/python benchmarks/mitsuba.py --mitsuba-python /tmp/mtsvenv/bin/python
        [--scene teapot-box] [--reps 15] [--threads 2] [--variant llvm_ad_rgb]

Mitsuba 3 lives in its own venv, never in reflect's (`python -m venv /tmp/mtsvenv &&
/tmp/mtsvenv/bin/pip install mitsuba`; its LLVM variants need a recent libLLVM: Debian 12's
own libLLVM-14 and -15 fail in Dr.Jit 1.5's code generation ("Cannot select ... fmaximum"),
so `apt-get install libllvm19` and set
`DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so`, which Dr.Jit does not find by
itself; seen with mitsuba 3.9.1). Without that python the script says it skipped and exits 0.

The scene is reflect's own, exported from its flattened frame-0 triangles: one Mitsuba mesh
per material (diffuse, its colour or checkerboard) and per mirror (a `conductor` with the
mirror's reflectance), the same camera (look-at, vertical fov, 640x480 or the scene's size),
1 sample per pixel, box filter. Mitsuba traces it with a small Whitted integrator written
against its API (`whitted` below, registered in the worker): a hit on a mirror follows the
mirror's sampled reflection with its weight, up to the same `max_depth` bounces; any other hit
adds its diffuse reflectance (reflect's `unlit` shading) and stops; a miss adds nothing (the
scene's background must be black). So both trace the same rays: primary rays and the mirror
bounces, no light or shadow rays. Only unlit scenes with planar (triangle) mirrors export.

Mitsuba runs in a subprocess (this file with `--worker`, under the Mitsuba python) that renders
one frame per request; the frames alternate with reflect's (one of each per round, medians
after warm-up, `--gap` seconds of idle before each), so a busy machine slows both alike.
With `--run N` each side renders N frames back to back a round, as a batch render does, and
the first of each run is not counted: it is the one whose threads wake from the idle gap.
Each side's CPU time for its frame (all threads of its process, Linux) is reported too, with
the other side's CPU time during that frame (which shows whether either spills onto the
other's frame).
A Mitsuba frame is `mi.render` of the scene (its JIT traces the integrator, finds the
compiled kernel in its cache, launches it) plus waiting for the image; its first frame, which
compiles the kernel (or loads it from Dr.Jit's disk cache), is reported apart.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


# ------------------------------------------------------------------------ the Mitsuba worker
def worker(spec_path: str) -> None:
    """Runs under the Mitsuba python: builds the exported scene, then answers one line per
    request on stdin ('frame' -> seconds of one render; 'image PATH' -> saves the image)."""
    here = Path(__file__).resolve().parent  # this file is "mitsuba.py" too: not on the path
    sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != here]
    import drjit as dr
    import mitsuba as mi

    # @dr.syntax recompiles `sample` from its source: the names it uses must be globals
    globals().update(dr=dr, mi=mi)
    spec = json.loads(Path(spec_path).read_text())
    mi.set_variant(spec["variant"])
    dr.set_thread_count(spec["threads"])

    class Whitted(mi.SamplingIntegrator):
        """Mirrors: follow the sampled (delta) reflection with its weight, up to max_depth
        bounces. Anything else: its diffuse reflectance (an unlit surface), then stop."""

        def __init__(self, props):
            super().__init__(props)
            self.max_depth = props.get("max_depth", 4)

        @dr.syntax
        def sample(self, scene, sampler, ray, medium=None, active=True):
            ray = mi.Ray3f(ray)
            color = mi.Spectrum(0.0)
            weight = mi.Spectrum(1.0)
            depth = mi.UInt32(0)
            first_valid = mi.Bool(False)
            active = mi.Bool(active)
            ctx = mi.BSDFContext()
            while dr.hint(active, label="whitted"):
                si = scene.ray_intersect(ray, active)
                valid = active & si.is_valid()
                first_valid |= valid & (depth == 0)
                bsdf = si.bsdf(ray)
                mirror = valid & mi.has_flag(bsdf.flags(), mi.BSDFFlags.DeltaReflection)
                surface = valid & ~mirror
                color = dr.select(surface, color + weight
                                  * bsdf.eval_diffuse_reflectance(si, surface), color)
                bs, w = bsdf.sample(ctx, si, sampler.next_1d(mirror), sampler.next_2d(mirror),
                                    mirror)
                weight = dr.select(mirror, weight * w, weight)
                ray = dr.select(mirror, si.spawn_ray(si.to_world(bs.wo)), ray)
                depth += 1
                active = mirror & (depth <= self.max_depth)
            return color, first_valid, []

    mi.register_integrator("whitted", lambda props: Whitted(props))
    data = np.load(spec["arrays"])
    scene_dict: dict = {
        "type": "scene",
        "integrator": {"type": "whitted", "max_depth": spec["max_depth"]},
        "sensor": {
            "type": "perspective",
            "fov": spec["fov_y"],
            "fov_axis": "y",
            "near_clip": spec["near"],
            "far_clip": spec["far"],
            "to_world": mi.ScalarTransform4f().look_at(origin=spec["eye"], target=spec["target"],
                                                       up=spec["up"]),
            "film": {"type": "hdrfilm", "width": spec["width"], "height": spec["height"],
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": 1},
        },
    }
    for k, mesh in enumerate(spec["meshes"]):
        corners = data[f"corners{k}"].reshape(-1, 3)
        uvs = data[f"uvs{k}"].reshape(-1, 2)
        props = mi.Properties()
        props["bsdf"] = mi.load_dict(_transforms(mi, mesh["bsdf"]))
        shape = mi.Mesh(f"mesh{k}", len(corners), len(corners) // 3, props,
                        has_vertex_normals=False, has_vertex_texcoords=True)
        params = mi.traverse(shape)
        params["vertex_positions"] = mi.Float(corners.ravel().astype(np.float32))
        params["faces"] = mi.UInt32(np.arange(len(corners), dtype=np.uint32))
        params["vertex_texcoords"] = mi.Float(uvs.ravel().astype(np.float32))
        params.update()
        scene_dict[f"mesh{k}"] = shape
    scene = mi.load_dict(scene_dict)
    print(json.dumps({"ready": mi.__version__, "variant": mi.variant()}), flush=True)
    for line in sys.stdin:
        words = line.split()
        if not words or words[0] == "quit":
            break
        t = time.perf_counter()
        image = mi.render(scene, spp=1, seed=0)
        dr.eval(image)
        dr.sync_thread()
        seconds = time.perf_counter() - t
        if words[0] == "image":
            np.save(words[1], np.asarray(image))
        print(json.dumps({"seconds": seconds}), flush=True)


def _transforms(mi, d):
    """The exported dict with its {"scale_uv": [su, sv]} placeholders made transforms."""
    if isinstance(d, dict):
        if "scale_uv" in d:
            return mi.ScalarTransform4f().scale([d["scale_uv"][0], d["scale_uv"][1], 1.0])
        return {k: _transforms(mi, v) for k, v in d.items()}
    return d


# ------------------------------------------------------------------------ reflect's side
def export(opened, folder: Path, variant: str, threads: int, max_depth: int) -> Path:
    """reflect's frame-0 triangles and camera as a worker spec (JSON + npz) in `folder`."""
    from reflectcli.scene.types import CHECKER, UNLIT

    scene = opened.scene
    if scene.shading != UNLIT or np.any(scene.background != 0):
        raise SystemExit("mitsuba.py exports unlit scenes with a black background only")
    geometry = scene.geometry(0)
    camera = opened.camera(0)
    arrays, meshes = {}, []
    objects, mats = geometry.objects, scene.materials
    for mat in np.unique(objects.material):
        pick = objects.material == mat
        f = mats.mat_f[mat]
        if mats.mat_i[mat, 0] == CHECKER:
            # reflect: square (floor(u * su) + floor(v * sv)) % 2 of size 1/s; Mitsuba's
            # checkerboard: two squares per unit of its uv, so uv scaled by s/2
            bsdf = {"type": "diffuse", "reflectance": {
                "type": "checkerboard",
                "color0": {"type": "rgb", "value": [float(x) for x in f[0:3]]},
                "color1": {"type": "rgb", "value": [float(x) for x in f[3:6]]},
                "to_uv": _scale_uv(f[6] / 2.0, f[7] / 2.0)}}
        elif mats.mat_i[mat, 0] == 0:
            bsdf = {"type": "diffuse",
                    "reflectance": {"type": "rgb", "value": [float(x) for x in f[0:3]]}}
        else:
            raise SystemExit("mitsuba.py exports solid and checker materials only")
        k = len(meshes)
        arrays[f"corners{k}"] = objects.corners[pick]
        arrays[f"uvs{k}"] = objects.uvs[pick]
        meshes.append({"bsdf": bsdf})
    mirror_tris = geometry.mirror_tris
    for m in range(scene.mirrors.count):
        if scene.mirrors.kind[m] != 0 or np.any(scene.mirrors.base[m] != 0):
            raise SystemExit("mitsuba.py exports planar mirrors with a black base only")
        pick = mirror_tris.surface == scene.n_objects + m
        k = len(meshes)
        # a mirror flush with a wall: reflect's depth test lets the mirror win the tie;
        # Mitsuba has no such rule, so the mirror moves 1e-4 of its distance toward the camera
        n, d = scene.mirrors.plane(m)
        side = np.sign(np.dot(n, camera.eye) + d) or 1.0
        shift = 1e-4 * (1.0 + abs(np.dot(n, camera.eye) + d)) * side * np.asarray(n)
        arrays[f"corners{k}"] = (mirror_tris.corners[pick] + shift).astype(np.float32)
        arrays[f"uvs{k}"] = mirror_tris.uvs[pick]
        r = [float(x) for x in scene.mirrors.reflectance[m]]
        meshes.append({"bsdf": {"type": "conductor", "material": "none",
                                "specular_reflectance": {"type": "rgb", "value": r}}})
    np.savez(folder / "arrays.npz", **arrays)
    spec = {
        "variant": variant, "threads": threads, "max_depth": max_depth,
        "arrays": str(folder / "arrays.npz"), "meshes": meshes,
        "eye": [float(x) for x in camera.eye], "target": [float(x) for x in camera.target],
        "up": [float(x) for x in camera.up], "fov_y": float(camera.fov_y),
        "near": float(camera.near), "far": float(camera.far),
        "width": camera.width, "height": camera.height,
    }
    path = folder / "spec.json"
    path.write_text(json.dumps(spec))
    return path


def _scale_uv(su: float, sv: float):
    """A placeholder the worker turns into mi.ScalarTransform4f().scale([su, sv, 1])."""
    return {"scale_uv": [float(su), float(sv)]}


class Worker:
    """The Mitsuba subprocess: one render per request."""

    def __init__(self, python: str, spec: Path) -> None:
        self.proc = subprocess.Popen([python, __file__, "--worker", str(spec)],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        self.ready = self._reply()

    def _reply(self) -> dict:
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError("the Mitsuba worker stopped (see its stderr above)")
        return json.loads(line)

    def frame(self, image: Path | None = None) -> float:
        self.proc.stdin.write(f"image {image}\n" if image else "frame\n")
        self.proc.stdin.flush()
        return self._reply()["seconds"]

    def cpu_seconds(self) -> float:
        """CPU time the worker process (all its threads) has used so far (Linux schedstat,
        nanoseconds; 0 where /proc is missing)."""
        total = 0
        try:
            tasks = os.listdir(f"/proc/{self.proc.pid}/task")
        except OSError:
            return 0.0
        for task in tasks:
            try:
                with open(f"/proc/{self.proc.pid}/task/{task}/schedstat") as f:
                    total += int(f.read().split()[0])
            except (OSError, ValueError, IndexError):
                pass
        return total * 1e-9

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.stdin.write("quit\n")
            self.proc.stdin.flush()
            self.proc.wait(timeout=60)


def compare(scene: str, python: str, reps: int, threads: int, variant: str,
            max_depth: int | None = None, gap: float = 0.1, run: int = 1,
            embree: str = "robust") -> dict | None:
    """Alternating frames of reflect's raytrace and Mitsuba's; None when Mitsuba is missing.
    Returns seconds per frame (arrays; also each side's CPU time for its frame, and the other
    side's CPU time during it), the Mitsuba first frame, rays, and an image check.
    `gap` seconds pass before each frame, so that neither frame starts while the other
    renderer's worker threads may still be spinning after its own. On a machine shared with
    other work, 2-thread figures mostly say whether the second core was free: reflect runs
    several parallel loops a frame, each waiting at its end for a thread that lost its core,
    where Mitsuba launches one kernel; 1 thread (`--threads 1`) is the steadier comparison.
    `run` > 1: each side renders `run` frames back to back after its gap, as a batch render
    does, and the first of each run (the one woken from the idle gap) is not counted.
    `embree`: reflect's raytrace parameter; "fast" builds its Embree scenes as Mitsuba
    builds its own (no robust flag, high build quality): like for like."""
    if not python or not Path(python).exists():
        return None
    from reflectcli import api

    overrides = [f"technique.max_depth={max_depth}"] if max_depth is not None else []
    overrides.append(f"technique.embree={embree}")
    opened = api.open_scene(str(ROOT / "scenes" / f"{scene}.toml"), technique="raytrace",
                            overrides=overrides, threads=threads, cache=False)
    opened.prepare()
    depth = opened.technique.params.max_depth
    with tempfile.TemporaryDirectory(prefix="reflect-mitsuba-") as tmp:
        folder = Path(tmp)
        spec = export(opened, folder, variant, threads, depth)
        worker = Worker(python, spec)
        try:
            first = worker.frame(folder / "image.npy")
            ours = opened.render_frame(0)
            theirs = np.load(folder / "image.npy")[..., :3]
            times = {"reflect": [], "mitsuba": []}
            # the other side's CPU time during each frame: a renderer whose threads still
            # spin (or work) while the other's frame runs would take its cores
            # and each side's own CPU time (all its threads) for its frame: at 1 thread the
            # work itself, whatever the machine's other load does to wall time
            busy = {"mitsuba_during_reflect": [], "reflect_during_mitsuba": [],
                    "reflect_cpu": [], "mitsuba_cpu": []}
            counted = 1 if run > 1 else 0  # frames of a run not counted
            for rep in range(reps + 2):  # two warm-up rounds
                time.sleep(gap)
                for k in range(run):
                    other, mine = worker.cpu_seconds(), time.process_time()
                    t = time.perf_counter()
                    opened.render_frame(0)
                    t_reflect = time.perf_counter() - t
                    other, mine = worker.cpu_seconds() - other, time.process_time() - mine
                    if rep >= 2 and k >= counted:
                        times["reflect"].append(t_reflect)
                        busy["mitsuba_during_reflect"].append(other)
                        busy["reflect_cpu"].append(mine)
                time.sleep(gap)
                for k in range(run):
                    their_cpu, mine_then = worker.cpu_seconds(), time.process_time()
                    t_mitsuba = worker.frame()
                    their_cpu, mine_then = (worker.cpu_seconds() - their_cpu,
                                            time.process_time() - mine_then)
                    if rep >= 2 and k >= counted:
                        times["mitsuba"].append(t_mitsuba)
                        busy["reflect_during_mitsuba"].append(mine_then)
                        busy["mitsuba_cpu"].append(their_cpu)
        finally:
            worker.close()
    diff = np.abs(ours.rgb - theirs).max(axis=-1)
    return {
        "reflect": np.array(times["reflect"]), "mitsuba": np.array(times["mitsuba"]),
        "mitsuba_first": first, "rays": ours.stats["rays"], "max_depth": depth,
        **{k: np.array(v) for k, v in busy.items()},
        "version": worker.ready, "size": ours.rgb.shape[:2],
        # 1 spp jitters Mitsuba's sample in the pixel: edges differ, flat areas agree
        "close": float(np.mean(diff < 0.02)),
    }


def ms(t: np.ndarray) -> str:
    p25, p50, p75 = np.percentile(t * 1e3, [25, 50, 75])
    return f"{p50:.2f} ms [{p25:.2f}-{p75:.2f}]"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mitsuba-python", default=os.environ.get("REFLECT_MITSUBA_PYTHON"),
                    help="a python with mitsuba (default: $REFLECT_MITSUBA_PYTHON)")
    ap.add_argument("--scene", default="teapot-box")
    ap.add_argument("--max-depth", type=int, default=None,
                    help="mirror bounces (default: the scene's raytrace max_depth)")
    ap.add_argument("--reps", type=int, default=15)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--gap", type=float, default=0.1,
                    help="seconds of idle before each frame (see compare)")
    ap.add_argument("--run", type=int, default=1,
                    help="frames each side renders back to back a round, the first not "
                         "counted (default 1: frames alternate one by one)")
    ap.add_argument("--embree", choices=("robust", "fast"), default="robust",
                    help="reflect's Embree scenes: robust (its default), or fast as Mitsuba "
                         "builds its own (no robust flag, high build quality)")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args.worker)
        return
    if not args.mitsuba_python or not Path(args.mitsuba_python).exists():
        print(f"mitsuba: skipped (no Mitsuba python: --mitsuba-python "
              f"{args.mitsuba_python or '(unset)'})")
        return
    import numba

    numba.set_num_threads(min(args.threads, numba.config.NUMBA_NUM_THREADS))
    r = compare(args.scene, args.mitsuba_python, args.reps, args.threads, args.variant,
                args.max_depth, args.gap, args.run, args.embree)
    h, w = r["size"]
    print(f"{args.scene}, {w}x{h}, 1 spp, max_depth {r['max_depth']}, {r['rays']:,} rays a "
          f"reflect frame; Mitsuba {r['version']['ready']} {r['version']['variant']}, "
          f"{args.threads} threads, reflect's Embree scenes {args.embree}"
          + (f"; runs of {args.run} frames back to back, the first not counted"
             if args.run > 1 else ""))
    print(f"  Mitsuba first frame (kernel compile or cache load): "
          f"{1e3 * r['mitsuba_first']:.1f} ms")
    print(f"  reflect raytrace: {ms(r['reflect'])}")
    print(f"  Mitsuba:          {ms(r['mitsuba'])}")
    print(f"  reflect / Mitsuba: {np.median(r['reflect']) / np.median(r['mitsuba']):.2f}x "
          f"(minima {r['reflect'].min() / r['mitsuba'].min():.2f}x; goal <= 1)")
    print(f"  CPU time a frame (all threads of each process): reflect {ms(r['reflect_cpu'])}, "
          f"Mitsuba {ms(r['mitsuba_cpu'])}: "
          f"{np.median(r['reflect_cpu']) / np.median(r['mitsuba_cpu']):.2f}x")
    print(f"  CPU of the other side during a frame (median): Mitsuba's worker during "
          f"reflect's {1e3 * np.median(r['mitsuba_during_reflect']):.2f} ms, reflect's "
          f"process during Mitsuba's {1e3 * np.median(r['reflect_during_mitsuba']):.2f} ms")
    print(f"  images: {100 * r['close']:.1f}% of pixels within 0.02 (Mitsuba jitters its "
          f"1 sample in the pixel)")


if __name__ == "__main__":
    main()
