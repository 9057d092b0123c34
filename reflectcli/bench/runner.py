"""Running a bench: references once, each run as an independent job, rows as they finish.

A job renders through `api.render` into <out>/runs/<run id>/ and scores its frames against
the ray-traced reference of the same scene, frames and scene overrides (rendered once into
<out>/references/<reference id>/ and reused). Jobs are pure functions of their description,
so local processes and a Dask cluster give the same rows as a serial run (timings aside).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import math
import os
import shutil
import statistics
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from ..errors import Problem, Problems
from ..output.exr import read_exr
from ..output.lock import folder_lock
from ..output.log import append_jsonl, read_jsonl
from .config import (
    MAX_REPEATS,
    MAX_RUNS,
    MAX_WORKERS,
    BenchConfig,
    expand,
    matrix_problems,
    run_count,
)
from .folders import check_bench_folder


def _digest(*parts) -> str:
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()[:12]


def scene_overrides(overrides: list[str]) -> list[str]:
    """The overrides that change the scene itself (everything but technique.*)."""
    return [o for o in overrides if not o.split("=", 1)[0].strip().startswith("technique")]


@contextmanager
def technique_notices_quiet():
    """No per-job "--technique X: the scene's ... parameters do not apply" notices: the bench
    chooses each run's technique on purpose (the user passed no --technique)."""
    quiet = logging.getLogger("reflect")
    level = quiet.level
    quiet.setLevel(logging.ERROR)
    try:
        yield
    finally:
        quiet.setLevel(level)


@dataclass
class BenchPlan:
    config: BenchConfig
    source: str
    out: str
    jobs: list[dict] = field(default_factory=list)


def load_bench(path: str, out: str | None = None, overrides: list[str] | tuple = ()
               ) -> BenchPlan:
    """Read and validate a bench file and every job in it (Problems name the bench file).
    `out` replaces the bench file's folder; `overrides` (bench --set) go on top of every
    run's own."""
    from .. import api

    if out is not None:
        api.check_output_root(out, "--out", "")
    display = os.path.relpath(path)
    cfg = api.load_settings(path, BenchConfig)
    problems = matrix_problems(cfg, display)  # from the list lengths: nothing expanded yet
    if run_count(cfg) > MAX_RUNS:
        raise Problems(problems)
    # an `out` written in the bench file is relative to it; the default is out/bench/<name>
    default_out = (os.path.join(os.path.dirname(os.path.abspath(path)), cfg.bench.out)
                   if cfg.bench.out else os.path.join("out", "bench", cfg.bench.name))
    plan = BenchPlan(cfg, path, out if out is not None else default_out)
    with technique_notices_quiet():
        _plan_jobs(plan, cfg, path, display, overrides, problems)
    if problems:
        # one line per problem: the same frames or reference_depth problem of every job once
        unique: dict[str, Problem] = {}
        for p in problems:
            unique.setdefault(str(p), p)
        raise Problems(list(unique.values())[:20])
    check_bench_folder(plan, *(("--out", "") if out is not None else (display, "bench.out")))
    return plan


def check_workers(workers: int) -> None:
    """`--workers` must be 1..MAX_WORKERS (one line, before anything is read)."""
    if not 1 <= workers <= MAX_WORKERS:
        raise Problems([Problem("--workers", "", f"must be 1..{MAX_WORKERS}")])


def _plan_jobs(plan: BenchPlan, cfg: BenchConfig, path: str, display: str,
               overrides: list[str] | tuple, problems: list[Problem]) -> None:
    from .. import api

    references: dict[tuple, tuple] = {}  # (scene, overrides) -> (name, hash, log) or Problems
    for i, job in enumerate(expand(cfg, path)):
        job["overrides"] = job["overrides"] + list(overrides)  # `bench --set`: on top
        job["override_fields"] = job["override_fields"] + [
            (o.split("=", 1)[0].strip(), None) for o in overrides]
        where = f"runs ({job['technique']} on {os.path.relpath(job['scene'])})"
        try:
            run = api.open_scene(job["scene"], overrides=job["overrides"],
                                 technique=job["technique"])
            selected = run.frames(job["frames"])
        except Problems as e:
            problems += [_job_problem(display, where, job, p) for p in e.problems]
            continue
        # the scene's content and the timing settings are in the id too: `--resume` re-runs
        # a job whose scene was edited or whose warm-up / repeats changed
        job["id"] = _digest(os.path.relpath(job["scene"]), job["technique"], job["overrides"],
                            job["frames"], run.scene_hash, cfg.bench.repeats, cfg.bench.warmup)
        job["repeats"] = run_repeats(cfg, len(selected))
        job["scene_name"] = run.name
        job["parameters"] = run.params.model_dump(mode="json")
        ref_overrides = scene_overrides(job["overrides"]) + [
            f"technique.max_depth={cfg.bench.reference_depth}"]
        key = (job["scene"], tuple(ref_overrides))
        if key not in references:
            try:
                ref = api.open_scene(job["scene"], overrides=ref_overrides,
                                     technique="raytrace")
                references[key] = (ref.name, ref.scene_hash, ref.config.output.log)
            except Problems as e:
                references[key] = e
        if isinstance(references[key], Problems):
            problems += [_job_problem(display, where, job, p, reference=True)
                         for p in references[key].problems]
            continue
        ref_name, ref_hash, ref_log = references[key]
        # the scene's content (files it reads included) is in the id: an edited scene gets a
        # new reference instead of being scored against the old one; so are its renders
        # (repeats, warm-up): a reference timed on too few renders is not reused once the
        # bench file asks for more (its `x raytrace` ratios stayed marked)
        job["reference"] = {
            "id": _digest(os.path.relpath(job["scene"]), ref_overrides, job["frames"],
                          ref_hash, job["repeats"], cfg.bench.warmup),
            "overrides": ref_overrides,
            "scene_name": ref_name,
            "log": ref_log,  # the reference folder's output.log (bench/folders.py)
        }
        job["index"] = i
        plan.jobs.append(job)


def _job_problem(display: str, where: str, job: dict, problem: Problem,
                 reference: bool = False) -> Problem:
    """A job's problem in the bench file's words: the frames and the reference depth are
    the bench file's own fields (the api names them --frames and technique.max_depth)."""
    if problem.file == "--frames":
        scene = os.path.relpath(job["scene"])
        return Problem(display, job["frames_field"], f"{problem.message} (in {scene})")
    if reference and problem.field == "technique.max_depth":
        return Problem(display, "bench.reference_depth", problem.message)
    if problem.file == "--technique" and not reference and problem.field == "technique.name":
        return Problem(display, job["techniques_field"], problem.message)
    if problem.file == "--set":  # a run's `set` or sweep value: named as the bench file has it
        run = f"{job['technique']} on {os.path.relpath(job['scene'])}"
        for key, field in reversed(job.get("override_fields", ())):  # the last one wins
            if key == problem.field or problem.field.startswith(key + ".") or \
                    key.startswith(problem.field + "."):
                if field is None:  # `bench --set`
                    break
                inner = "" if field.endswith("." + problem.field) else f"{problem.field}: "
                return Problem(display, field, f"{inner}{problem.message} ({run})")
    return Problem(display, where, str(problem))


def render_reference(plan: BenchPlan, job: dict, threads: int | None = None
                     ) -> tuple[str, str]:
    """The reference frames of a job (rendered once, then found on disk): (folder, log)."""
    from .. import api

    folder = os.path.join(plan.out, "references", job["reference"]["id"])
    opened = api.open_scene(job["scene"], technique="raytrace",
                            overrides=job["reference"]["overrides"], threads=threads)
    # the images are reused, but their times are the `x raytrace` ratio's other side: a
    # reference timed at another thread count or on another CPU (an earlier bench run with
    # another --threads) is rendered again, not set against this run's times
    resume = _timed_alike(opened, folder, threads)
    result = opened.write_frames(opened.frames(job["frames"]), out=folder, resume=resume,
                                 repeats=job.get("repeats", plan.config.bench.repeats))
    return result.folder, result.log


def resolved_threads(threads: int | None) -> int:
    """The thread count a render asked for `threads` runs at (None: numba's own)."""
    import numba

    return threads if threads is not None else numba.config.NUMBA_NUM_THREADS


def _timed_alike(opened, folder: str, threads: int | None) -> bool:
    """Whether the reference frames already in `folder` (if any) were timed at this thread
    count on this CPU by this code (provenance.source_digest), so that their times may be
    set against this run's and their images stand for what this ray tracer renders."""
    from ..output.identity import logged_rows
    from ..provenance import cpu_name, source_digest

    frames = os.path.join(folder, opened.name, opened.technique_name)
    rows = logged_rows(os.path.join(frames, opened.config.output.log))
    return all(r.get("threads") == resolved_threads(threads) and r.get("cpu") == cpu_name()
               and r.get("versions", {}).get("source") == source_digest()
               for r in rows.values())


MIN_TIMED = 3  # frame times are medians of at least this many timed renders...
MIN_WARMUP = 1  # ...after at least this many warm-up renders


def run_repeats(cfg: BenchConfig, frame_count: int) -> int:
    """Renders of each frame of a run: the bench file's `repeats` if it sets them, otherwise
    enough that `warmup` + MIN_TIMED renders are made (a still scene is not timed on one cold
    render). A bench file that sets fewer gets them, and the timing warning with them."""
    repeats = cfg.bench.repeats
    if "repeats" in cfg.bench.model_fields_set:
        return repeats
    needed = cfg.bench.warmup + MIN_TIMED
    if frame_count * repeats < needed:
        repeats = min(MAX_REPEATS, math.ceil(needed / max(frame_count, 1)))
    return repeats
SCOPES = ("mirror", "image")
MEAN_OF_FRAMES = ("rmse", "frac_off", "relmse", "p50", "p95", "p99", "flip", "flip_ldr", "ssim")


def timing_samples(log: list[dict]) -> list[float]:
    """Every render's seconds in the order rendered (repeats of a frame included)."""
    return [t for row in log for t in row.get("repeat_seconds", [row["frame_seconds"]])]


def timing_stats(samples: list[float], warmup: int) -> dict:
    """Median and p25-p75 (ms) of the renders after `warmup`; `timing_warning` says when
    fewer than MIN_TIMED renders were timed after fewer than MIN_WARMUP warm-up renders.
    Asked for more warm-up renders than there are, the last render is timed anyway."""
    warm = min(warmup, len(samples) - 1)
    timed = samples[warm:]
    problems = []
    if warm < MIN_WARMUP:
        problems.append(f"{warm} warm-up")
    if len(timed) < MIN_TIMED:
        problems.append(f"{len(timed)} timed")
    return {
        "frame_ms_median": 1e3 * statistics.median(timed),
        "frame_ms_p25": 1e3 * float(np.percentile(timed, 25)),
        "frame_ms_p75": 1e3 * float(np.percentile(timed, 75)),
        "first_frame_ms": 1e3 * samples[0],
        "warmup_renders": warm, "timed_frames": len(timed),
        "timing_warning": (", ".join(problems) + f" (want >= {MIN_WARMUP} warm-up, "
                           f">= {MIN_TIMED} timed)") if problems else "",
    }


def _reference_timing(stats: dict, ref_rows: list[dict], run_row: dict) -> dict:
    """The reference's frame time for the `x raytrace` ratio, with its own timing warning
    (a ratio is only as good as its worse side): too few renders, or renders timed at
    another thread count or on another CPU than the run's (a Dask worker elsewhere)."""
    warning = [stats["timing_warning"]] if stats["timing_warning"] else []
    for key, what in (("threads", "threads"), ("cpu", "CPU")):
        theirs = sorted({str(r.get(key)) for r in ref_rows})
        if theirs != [str(run_row.get(key))]:
            warning.append(f"reference timed at {what} {', '.join(theirs)}, "
                           f"this run at {run_row.get(key)}")
    return {"reference_ms_median": stats["frame_ms_median"],
            "reference_timing_warning": "; ".join(warning)}


def timing_warned(rows: list[dict]) -> list[dict]:
    """The rows whose frame time, or whose reference's, carries a timing warning."""
    return [r for r in rows if r.get("timing_warning") or r.get("reference_timing_warning")]


def _rgb(channels: dict) -> np.ndarray:
    return np.stack([channels[c] for c in "RGB"], axis=-1)


def execute_job(job: dict, settings: dict) -> dict:
    """Render one run, score it against its reference; the result row (plain JSON data)."""
    from .. import api
    from ..metrics import METRICS, score
    from ..metrics.temporal import temporal_errors

    folder = os.path.join(settings["out"], "runs", job["id"])
    repeats = job.get("repeats", settings.get("repeats", 1))
    shutil.rmtree(folder, ignore_errors=True)  # a run without a result row starts over
    load_before = _load()
    with technique_notices_quiet():
        result = api.render(job["scene"], out=folder,
                            frames=job.get("frames", settings["frames"]),
                            technique=job["technique"], overrides=job["overrides"],
                            cache=os.path.join(settings["out"], "cache"),
                            threads=settings.get("threads"), repeats=repeats)
    load = [load_before, _load()]  # the machine's 1-minute load around the renders
    frames_dir = result.folder
    log = read_jsonl(result.log)  # the scene's output.log, whatever it is named
    ref_dir, ref_log_path = settings["reference_dirs"][job["reference"]["id"]]
    ref_log = {r["file"]: r for r in read_jsonl(ref_log_path)}
    per_frame = []
    images: dict[str, list] = {"test": [], "ref": [], "mirror": []}
    for row in log:
        ours, _ = read_exr(os.path.join(frames_dir, row["file"]))
        ref, _ = read_exr(os.path.join(ref_dir, row["file"]))
        a, b = _rgb(ours), _rgb(ref)
        mirror = (ours["mirror"] > 0) & (ref["mirror"] > 0)
        scores = score(a, b, {"mirror": mirror, "image": None},
                       threshold=settings["threshold"], metrics=METRICS)
        per_frame.append({
            "frame": row["frame"],
            **{f"{k}_{scope}": v for scope in SCOPES for k, v in scores[scope].items()},
            **hole_fractions(ours, ref, mirror, row),
        })
        for key, value in (("test", a), ("ref", b), ("mirror", mirror)):
            images[key].append(value)
    # temporal error: frame t against t-1, over the mirror in both images at both frames
    both = [None] + [images["mirror"][t] & images["mirror"][t - 1]
                     for t in range(1, len(per_frame))]
    for scope, masks in (("mirror", both), ("image", None)):
        errors, total = temporal_errors(images["test"], images["ref"], masks)
        for f, e in zip(per_frame, [None, *errors], strict=True):  # frame 0 has no change
            f[f"temporal_{scope}"] = e
        per_frame[0][f"temporal_{scope}_total"] = total
    first = log[0]
    out = {
        "run": job["id"], "scene": job["scene_name"],
        "scene_file": os.path.relpath(job["scene"]), "technique": job["technique"],
        "sweep": job["sweep"], "overrides": job["overrides"], "parameters": job["parameters"],
        "frames": len(per_frame), "repeats": repeats,
        **timing_stats(timing_samples(log), settings["warmup"]),
        **_reference_timing(timing_stats(timing_samples([ref_log[r["file"]] for r in log]),
                                         settings["warmup"]),
                            [ref_log[r["file"]] for r in log], first),
        # one-time work, never in frame time: everything the technique does before its first
        # frame (map capture, decomposition, ...); first_frame_ms shows first-frame caches
        "prepare_seconds": float(first.get("prepare_seconds", 0.0)),
        # maps (re)captured, amortised over every frame of the run (the one-time capture in
        # prepare included): what an update policy costs per frame
        "capture_ms_per_frame": 1e3 * (
            float(first.get("precompute_seconds", 0.0))
            + sum(r.get("stages", {}).get("capture", 0.0) for r in log)) / len(log),
        "numba_compile_seconds": float(first["numba_compile_seconds"]),
        "triangles": int(first.get("triangles", 0)),
        "threads": first["threads"], "cpu": first["cpu"], "versions": first["versions"],
        "load_1min": load, "cores": os.cpu_count(),
        "images": [os.path.join(frames_dir, r["file"]) for r in log],
        "reference_images": [os.path.join(ref_dir, r["file"]) for r in log],
    }
    for scope in SCOPES:
        for m in METRICS:
            values = [f[f"{m}_{scope}"] for f in per_frame]
            key = f"{m}_{scope}"
            if m == "psnr":
                out[key] = _mean_psnr(values)
            elif m == "max_error":
                out[key] = _nan_reduce(np.max, values)
            else:
                out[key] = _nan_reduce(np.mean, values)
        out[f"temporal_{scope}"] = per_frame[0].pop(f"temporal_{scope}_total")
    for key in ("hole_fraction", "unreached_fraction"):
        out[key] = float(np.mean([f[key] for f in per_frame]))
    out["per_frame"] = per_frame
    return out


def _load() -> float | None:
    """The 1-minute load average (None where the system has none): a run timed while
    other work wanted the cores has frame times that include waiting for them."""
    try:
        return round(os.getloadavg()[0], 2)
    except OSError:
        return None


def _nan_reduce(fn, values: list[float]) -> float:
    finite = [v for v in values if not math.isnan(v)]
    return float(fn(finite)) if finite else math.nan


def hole_fractions(ours: dict, ref: dict, mirror: np.ndarray, row: dict) -> dict:
    """`hole_fraction`: of the mirror pixels whose reflection the reference shows as
    geometry (its `reflected_hit` channel), those the technique left as holes (its `holes`
    channel); `unreached_fraction`: the technique's raw figure from its log (every mirror
    pixel it did not reach, background reflections included)."""
    unreached = float(row.get("unreached_fraction", 0.0))
    if "holes" not in ours or "reflected_hit" not in ref:
        return {"hole_fraction": unreached if "holes" in ours else 0.0,
                "unreached_fraction": unreached}
    should = mirror & (ref["reflected_hit"] >= 0.5)
    holes = should & (ours["holes"] > 0)
    return {"hole_fraction": float(holes.sum() / max(int(should.sum()), 1)),
            "unreached_fraction": unreached}


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
              overrides: list[str] | tuple = (), plan: BenchPlan | None = None
              ) -> BenchResult:
    """Run a bench file's matrix (`plan`: the file already loaded with these `out` and
    `overrides`, not checked again)."""
    from .. import api

    check_workers(workers)
    if plan is None:
        plan = load_bench(path, out, overrides)
    api.check_threads(threads)  # bad arguments before the lock makes the folder
    if scheduler is not None:
        check_scheduler(scheduler)  # fail fast, before any reference is rendered
    with folder_lock(plan.out, "--out" if out is not None else os.path.relpath(path)):
        return _run_plan(plan, resume, workers, scheduler, threads, on_row)


def _run_plan(plan: BenchPlan, resume: bool, workers: int, scheduler: str | None,
              threads: int | None, on_row: Callable[[dict], None] | None) -> BenchResult:
    os.makedirs(plan.out, exist_ok=True)
    rows_path = os.path.join(plan.out, "results.jsonl")
    done: dict[str, dict] = {}
    if os.path.exists(rows_path):
        if resume:
            done = {r["run"]: r for r in read_jsonl(rows_path)}
        else:
            os.unlink(rows_path)
    if not resume:
        # the last bench's report, table and plots go with its rows: none of them may be
        # left beside this run's rows if it stops before its own are written
        remove_outputs(plan.out)
    pending = [j for j in plan.jobs if j["id"] not in done]
    reference_dirs = {}
    for job in plan.jobs:
        ref = job["reference"]["id"]
        if ref not in reference_dirs:
            reference_dirs[ref] = render_reference(plan, job, threads)
    settings = {"out": plan.out, "frames": plan.config.bench.frames,
                "warmup": plan.config.bench.warmup, "repeats": plan.config.bench.repeats,
                "threshold": plan.config.bench.threshold,
                "reference_dirs": reference_dirs, "threads": threads}

    def keep(row: dict) -> None:
        append_jsonl(rows_path, row)
        done[row["run"]] = row
        if on_row is not None:
            on_row(row)

    try:
        for row in _execute(pending, settings, workers, scheduler):
            keep(row)
    except BaseException:
        # interrupted or failed: report.md and results.csv of the runs finished so far,
        # marked incomplete (never the previous bench's beside this one's rows); no plots
        finished = [done[j["id"]] for j in plan.jobs if j["id"] in done]
        with contextlib.suppress(OSError):
            write_outputs(plan, finished, total=len(plan.jobs), plots=False)
        raise
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

        from .. import openmp

        # spawn: a fork after numba's OpenMP threads have started aborts (STACK-NOTES.md);
        # the workers share the cores, so their idle threads sleep at once (openmp.py)
        with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                                 initializer=openmp.no_spin if openmp.defaulted else None) as ex:
            futures = [ex.submit(execute_job, job, settings) for job in jobs]
            for f in futures:
                yield f.result()
        return
    for job in jobs:
        yield execute_job(job, settings)


PLOT_PATTERNS = ("time-vs-triangles.png", "error-vs-*.png", "pareto-*.png", "contact-*.png")


def remove_outputs(out: str, keep: tuple[str, ...] | list[str] = (), *,
                   results: bool = True) -> None:
    """Remove the bench's report, table (with `results`) and plot files in `out` but those
    in `keep`: a plot of a scene or sweep no longer in the bench would otherwise sit beside
    the new ones as if it were this run's."""
    import glob

    names = [os.path.join(out, n) for n in ("results.csv", "report.md")] if results else []
    for pattern in PLOT_PATTERNS:
        names += glob.glob(os.path.join(glob.escape(out), pattern))
    kept = {os.path.abspath(k) for k in keep}
    for name in names:
        if os.path.abspath(name) not in kept and os.path.isfile(name) \
                and not os.path.islink(name):
            os.unlink(name)


def write_outputs(plan, rows: list[dict], total: int | None = None, plots: bool = True
                  ) -> None:
    """results.csv, report.md and (with the plots extra) the plots of a bench's rows; `total`
    runs planned (fewer rows: the report says it is incomplete). Here, not in report.py:
    plots.py builds on report.py, so report.py must not import it."""
    from .report import report_markdown, write_csv, write_text

    out = plan.out
    write_csv(os.path.join(out, "results.csv"), rows)
    write_text(os.path.join(out, "report.md"),
               report_markdown(plan.config.bench.name, rows, total))
    if plots and plan.config.bench.plots:
        try:
            from .plots import write_plots
        except ImportError:
            return  # matplotlib is an optional extra
        remove_outputs(out, write_plots(out, rows), results=False)
