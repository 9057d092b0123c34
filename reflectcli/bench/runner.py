"""Running a bench: references once, each run as an independent job, rows as they finish.

A job renders through `api.render` into <out>/runs/<run id>/ and scores its frames against
the ray-traced reference of the same scene, frames and scene overrides (rendered once into
<out>/references/<reference id>/ and reused). Jobs are pure functions of their description,
so local processes and a Dask cluster give the same rows as a serial run (timings aside).
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
import statistics
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import Problem, Problems
from ..output.exr import read_exr
from ..output.lock import folder_lock
from ..output.log import append_jsonl, read_jsonl
from ..scene.build import scene_hashes
from .config import BenchConfig, expand
from .metrics import METRIC_NAMES, image_metrics


def _digest(*parts) -> str:
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()[:12]


def scene_overrides(overrides: list[str]) -> list[str]:
    """The overrides that change the scene itself (everything but technique.*)."""
    return [o for o in overrides if not o.split("=", 1)[0].strip().startswith("technique")]


@dataclass
class BenchPlan:
    config: BenchConfig
    source: str
    out: str
    jobs: list[dict] = field(default_factory=list)


def load_bench(path: str, out: str | None = None, overrides: list[str] | tuple = ()
               ) -> BenchPlan:
    """Read and validate a bench file and every job in it (Problems name the bench file)."""
    from pydantic import ValidationError

    from ..config.load import read_toml, validation_problems

    display = os.path.relpath(path)
    data = read_toml(path)
    try:
        cfg = BenchConfig.model_validate(data)
    except ValidationError as e:
        raise Problems(validation_problems(e, data, {}, display)) from None
    # an `out` written in the bench file is relative to it; the default is out/bench/<name>
    default_out = (os.path.join(os.path.dirname(os.path.abspath(path)), cfg.bench.out)
                   if cfg.bench.out else os.path.join("out", "bench", cfg.bench.name))
    plan = BenchPlan(cfg, path, out if out is not None else default_out)
    problems = []
    quiet = logging.getLogger("reflect")
    level = quiet.level
    quiet.setLevel(logging.ERROR)  # per-job --technique notices: the bench chooses on purpose
    try:
        _plan_jobs(plan, cfg, path, display, overrides, problems)
    finally:
        quiet.setLevel(level)
    if problems:
        raise Problems(problems[:20])
    return plan


def _plan_jobs(plan, cfg, path, display, overrides, problems) -> None:
    from ..config.load import load_config

    for i, job in enumerate(expand(cfg, path)):
        job["overrides"] = job["overrides"] + list(overrides)  # `bench --set`: on top
        try:
            scene_cfg, _ = load_config(job["scene"], job["overrides"], job["technique"])
        except Problems as e:
            where = f"runs ({job['technique']} on {os.path.relpath(job['scene'])})"
            problems += [Problem(display, where, str(p)) for p in e.problems]
            continue
        job["id"] = _digest(os.path.relpath(job["scene"]), job["technique"], job["overrides"],
                            cfg.bench.frames)
        job["scene_name"] = scene_cfg.scene.name
        job["parameters"] = scene_cfg.technique.model_dump(mode="json")
        ref_overrides = scene_overrides(job["overrides"]) + [
            f"technique.max_depth={cfg.bench.reference_depth}"]
        ref_cfg, _ = load_config(job["scene"], ref_overrides, "raytrace")
        # the scene's content (files it reads included) is in the id: an edited scene gets a
        # new reference instead of being scored against the old one
        job["reference"] = {
            "id": _digest(os.path.relpath(job["scene"]), ref_overrides, cfg.bench.frames,
                          scene_hashes(ref_cfg, job["scene"])[0]),
            "overrides": ref_overrides,
            "scene_name": ref_cfg.scene.name,
        }
        job["index"] = i
        plan.jobs.append(job)


def render_reference(plan: BenchPlan, job: dict, threads: int | None = None) -> str:
    """The reference frames of a job (rendered once, then found on disk)."""
    from .. import api

    folder = os.path.join(plan.out, "references", job["reference"]["id"])
    result = api.render(job["scene"], out=folder, frames=plan.config.bench.frames,
                        technique="raytrace", overrides=job["reference"]["overrides"],
                        resume=True, threads=threads)
    return result.folder


def execute_job(job: dict, settings: dict) -> dict:
    """Render one run, score it against its reference; the result row (plain JSON data)."""
    from .. import api

    folder = os.path.join(settings["out"], "runs", job["id"])
    shutil.rmtree(folder, ignore_errors=True)  # a run without a result row starts over
    result = api.render(job["scene"], out=folder, frames=settings["frames"],
                        technique=job["technique"], overrides=job["overrides"],
                        cache=os.path.join(settings["out"], "cache"),
                        threads=settings.get("threads"))
    frames_dir = result.folder
    log = read_jsonl(os.path.join(frames_dir, "timings.jsonl"))
    ref_dir = settings["reference_dirs"][job["reference"]["id"]]
    ref_log = {r["file"]: r for r in read_jsonl(os.path.join(ref_dir, "timings.jsonl"))}
    per_frame = []
    for row in log:
        ours, _ = read_exr(os.path.join(frames_dir, row["file"]))
        ref, _ = read_exr(os.path.join(ref_dir, row["file"]))
        a = np.stack([ours[c] for c in "RGB"], axis=-1)
        b = np.stack([ref[c] for c in "RGB"], axis=-1)
        mirror = (ours["mirror"] > 0) & (ref["mirror"] > 0)
        m_all = image_metrics(a, b, None, settings["threshold"])
        m_mir = image_metrics(a, b, mirror, settings["threshold"])
        per_frame.append({
            **{f"{k}_image": v for k, v in m_all.items()},
            **{f"{k}_mirror": v for k, v in m_mir.items()},
            "hole_fraction": float(row.get("hole_fraction", 0.0)),
            "frame_seconds": row["frame_seconds"],
            "reference_seconds": ref_log[row["file"]]["frame_seconds"],
        })
    warm = min(settings["warmup"], len(per_frame) - 1)
    timed = per_frame[warm:]
    times = sorted(f["frame_seconds"] for f in timed)
    ref_times = [f["reference_seconds"] for f in timed]
    first = log[0]
    out = {
        "run": job["id"], "scene": job["scene_name"],
        "scene_file": os.path.relpath(job["scene"]), "technique": job["technique"],
        "sweep": job["sweep"], "overrides": job["overrides"], "parameters": job["parameters"],
        "frames": len(per_frame), "timed_frames": len(timed),
        "frame_ms_median": 1e3 * statistics.median(times),
        "frame_ms_p25": 1e3 * float(np.percentile(times, 25)),
        "frame_ms_p75": 1e3 * float(np.percentile(times, 75)),
        "reference_ms_median": 1e3 * statistics.median(ref_times),
        "precompute_seconds": float(first.get("stages", {}).get("precompute", 0.0)),
        "numba_compile_seconds": float(first["numba_compile_seconds"]),
        "triangles": int(first.get("triangles", 0)),
        "threads": first["threads"], "cpu": first["cpu"], "versions": first["versions"],
        "images": [os.path.join(frames_dir, r["file"]) for r in log],
        "reference_images": [os.path.join(ref_dir, r["file"]) for r in log],
    }
    for key in [f"{m}_{part}" for m in METRIC_NAMES for part in ("mirror", "image")]:
        values = [f[key] for f in per_frame]
        out[key] = float(np.mean(values)) if key.startswith(("rmse", "frac")) else (
            float(np.max(values)) if key.startswith("max") else _mean_psnr(values))
    out["hole_fraction"] = float(np.mean([f["hole_fraction"] for f in per_frame]))
    return out


def _mean_psnr(values: list[float]) -> float:
    """PSNR of the mean squared error over frames (inf only if every frame is exact)."""
    finite = [v for v in values if not np.isnan(v)]
    if not finite:
        return float("nan")
    mses = [0.0 if np.isinf(v) else 10 ** (-v / 10) for v in finite]
    mse = float(np.mean(mses))
    return float("inf") if mse == 0 else -10 * float(np.log10(mse))


@dataclass
class BenchResult:
    out: str
    rows: list[dict]
    ran: int
    skipped: int


def run_bench(path: str, *, resume: bool = False, workers: int = 1,
              scheduler: str | None = None, threads: int | None = None,
              on_row: Callable[[dict], None] | None = None, out: str | None = None,
              overrides: list[str] | tuple = ()) -> BenchResult:
    plan = load_bench(path, out, overrides)
    if scheduler is not None:
        check_scheduler(scheduler)
    with folder_lock(plan.out, "--out" if out is not None else os.path.relpath(path)):
        return _run_plan(plan, resume, workers, scheduler, threads, on_row)


def _run_plan(plan, resume, workers, scheduler, threads, on_row) -> BenchResult:
    from .report import write_outputs

    os.makedirs(plan.out, exist_ok=True)
    rows_path = os.path.join(plan.out, "results.jsonl")
    done: dict[str, dict] = {}
    if os.path.exists(rows_path):
        if resume:
            done = {r["run"]: r for r in read_jsonl(rows_path)}
        else:
            os.unlink(rows_path)
    pending = [j for j in plan.jobs if j["id"] not in done]
    reference_dirs = {}
    for job in plan.jobs:
        ref = job["reference"]["id"]
        if ref not in reference_dirs:
            reference_dirs[ref] = render_reference(plan, job, threads)
    settings = {"out": plan.out, "frames": plan.config.bench.frames,
                "warmup": plan.config.bench.warmup, "threshold": plan.config.bench.threshold,
                "reference_dirs": reference_dirs, "threads": threads}

    def keep(row: dict) -> None:
        append_jsonl(rows_path, row)
        done[row["run"]] = row
        if on_row is not None:
            on_row(row)

    for row in _execute(pending, settings, workers, scheduler):
        keep(row)
    rows = [done[j["id"]] for j in plan.jobs]
    write_outputs(plan, rows)
    return BenchResult(plan.out, rows, len(pending), len(plan.jobs) - len(pending))


def _connect(client_class, scheduler: str):
    """A Dask client, or one line within seconds when no scheduler answers."""
    try:
        return client_class(scheduler, timeout="5s")
    except (OSError, TimeoutError, ValueError) as e:
        reason = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise Problems([Problem("--scheduler", "", f"no Dask scheduler answers at "
                                f"'{scheduler}' ({reason[:120]})")]) from None


def check_scheduler(scheduler: str) -> None:
    """Fail fast, before any reference is rendered."""
    try:
        from dask.distributed import Client
    except ImportError:
        raise Problems([Problem("--scheduler", "", "needs the dask extra: "
                                "pip install 'reflect[dask]'")]) from None
    _connect(Client, scheduler).close()


def _execute(jobs, settings, workers, scheduler):
    """Yield result rows in job order: serially, in local processes, or on a Dask cluster."""
    if scheduler is not None:
        try:
            from dask.distributed import Client
        except ImportError:
            raise Problems([Problem("--scheduler", "", "needs the dask extra: "
                                    "pip install 'reflect[dask]'")]) from None
        with _connect(Client, scheduler) as client:
            futures = client.map(execute_job, jobs, settings=settings, pure=False)
            for f in futures:
                yield f.result()
        return
    if workers > 1:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        # spawn: a fork after numba's OpenMP threads have started aborts (STACK-NOTES.md)
        with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as ex:
            futures = [ex.submit(execute_job, job, settings) for job in jobs]
            for f in futures:
                yield f.result()
        return
    for job in jobs:
        yield execute_job(job, settings)
