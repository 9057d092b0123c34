"""The library face: load a scene, render its frames, write them. The CLI and bench call this."""

from __future__ import annotations

import contextlib
import json
import logging
import os
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from .camera import camera_from_config
from .config.load import load_config
from .config.scene import SceneConfig
from .errors import Problem, Problems
from .frame import Frame
from .maps.cache import MapCache, default_cache_dir
from .output.exr import write_exr
from .output.failures import discard, write_failure
from .output.finite import check_finite
from .output.identity import (
    check_same_overrides,
    logged_rows,
    matches,
    new_run_id,
    scene_identity,
)
from .output.log import append_jsonl
from .output.paths import inside, remove_stale_temps
from .output.png import write_png
from .provenance import cpu_name, versions
from .scene.build import build_scene
from .techniques.registry import TECHNIQUES


@dataclass
class RenderResult:
    folder: str
    written: list[str] = field(default_factory=list)
    skipped: list[int] = field(default_factory=list)
    compile_seconds: float = 0.0


@contextlib.contextmanager
def interrupts_deferred():
    """Hold Ctrl-C until the block ends, so an interrupted run never keeps a frame without
    its log line. Signal handlers can only be set from the main thread."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list = []
    previous = {sig: signal.signal(sig, lambda *args: caught.append(args))
                for sig in (signal.SIGINT, signal.SIGTERM)}  # SIGTERM is handled like Ctrl-C
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if caught:
        raise KeyboardInterrupt


def parse_frames(spec: str | None, count: int) -> range:
    """`None` -> all frames; `N` -> frame N; `A:B[:S]` -> frames A..B-1 every S (either end
    may be empty; B is clamped to the frame count)."""
    if spec is None:
        return range(count)
    try:
        if ":" in spec:
            a, b, *step = spec.split(":")
            if len(step) > 1:
                raise ValueError(spec)
            stride = int(step[0]) if step and step[0] else 1
            if stride < 1:
                raise ValueError(spec)
            r = range(int(a) if a else 0, min(int(b), count) if b else count, stride)
        else:
            r = range(int(spec), int(spec) + 1)
    except ValueError:
        message = f"expected N, A:B or A:B:S, got '{spec}'"
        raise Problems([Problem("--frames", "", message)]) from None
    if len(r) == 0 or r.start < 0 or r.stop > count:
        raise Problems([Problem("--frames", "", f"'{spec}' selects no frame of 0..{count - 1}")])
    return r


def prepare_output(folder: str, source: str, field: str) -> None:
    """Create the frame folder and prove it writable before any rendering starts."""
    try:
        os.makedirs(folder, exist_ok=True)
        probe = os.path.join(folder, f".write-test-{os.getpid()}")
        with open(probe, "w"):
            pass
        os.unlink(probe)
    except OSError as e:
        raise Problems(
            [Problem(source, field, f"cannot write to '{folder}': {e.strerror}")]
        ) from None


def write_missing_preview(exr: str) -> None:
    """--resume --preview: the PNG of a kept frame, from its EXR."""
    import numpy as np

    from .output.exr import read_exr

    channels, _ = read_exr(exr)
    write_png(exr[:-4] + ".png", np.stack([channels[c] for c in "RGB"], axis=-1))


def frame_channels(frame: Frame) -> dict:
    channels = {
        "R": frame.rgb[:, :, 0],
        "G": frame.rgb[:, :, 1],
        "B": frame.rgb[:, :, 2],
        "A": frame.alpha,
        "Z": frame.depth,
        "mirror": frame.mirror_mask.astype("float32"),
    }
    channels.update(frame.extra)
    return channels


_warmed: dict[tuple, float] = {}


def warm_up(technique_name: str, params_json: str, threads: int) -> float:
    """Compile (or load from cache) the technique's numba kernels on a tiny scene; seconds."""
    key = (technique_name, params_json)
    if key in _warmed:
        return 0.0
    from .warmup import warm_params, warm_scene

    start = time.perf_counter()
    notice = threading.Timer(3.0, logging.getLogger("reflect").info, (
        "compiling the numba kernels (the first run takes about 20 s; later runs load them "
        "from the cache)",))
    notice.daemon = True
    notice.start()
    scene, camera = warm_scene()
    cls = TECHNIQUES[technique_name]
    technique = cls(cls.Params.model_validate_json(warm_params(params_json)), threads)
    logger = logging.getLogger("reflect")
    level = logger.level
    logger.setLevel(logging.ERROR)  # the warm-up scene's notices are nobody's business
    try:
        technique.render(technique.prepare(scene), 0, camera)
    finally:
        logger.setLevel(level)
        notice.cancel()
    _warmed[key] = time.perf_counter() - start
    return _warmed[key]


def render(
    path: str,
    *,
    out: str | None = None,
    frames: str | None = None,
    technique: str | None = None,
    overrides: tuple[str, ...] | list[str] = (),
    preview: bool | None = None,
    threads: int | None = None,
    resume: bool = False,
    on_frame: Callable[[int, str], None] | None = None,
    config: SceneConfig | None = None,
    cache: str | None = None,
) -> RenderResult:
    """Render the selected frames of a scene file into out/<scene>/<technique>/.

    Raises Problems for bad input before anything is written.
    """
    import numba

    display = os.path.relpath(path) if not os.path.relpath(path).startswith("..") else path
    if config is None:
        config, _ = load_config(path, overrides, technique)
    selected = parse_frames(frames, config.camera.frame_count)
    name = config.technique.name
    if threads is not None and not 1 <= threads <= numba.config.NUMBA_NUM_THREADS:
        raise Problems([Problem("--threads", "", f"must be 1..{numba.config.NUMBA_NUM_THREADS}")])
    scene = build_scene(config, path)  # before any folder is made: it may still reject input
    root = out if out is not None else config.output.dir
    folder = inside(inside(root, config.scene.name, display, "scene.name"), name, display)
    prepare_output(
        folder, "--out" if out is not None else display, "" if out is not None else "output.dir"
    )
    remove_stale_temps(folder)
    log_path = inside(folder, config.output.log, display, "output.log")
    stored = logged_rows(log_path)
    check_same_overrides(stored, list(overrides), folder, "--set" if overrides else display)
    if threads is not None:
        numba.set_num_threads(threads)
    threads = numba.get_num_threads()
    params = config.technique
    params_json = params.model_dump_json()
    result = RenderResult(folder)
    result.compile_seconds = warm_up(name, params_json, threads)
    cls = TECHNIQUES[name]
    tech = cls(params, threads, cache if cache is not None else default_cache_dir(path))
    t0 = time.perf_counter()
    state = tech.prepare(scene)
    prepare_seconds = time.perf_counter() - t0
    preview = config.output.preview if preview is None else preview
    scene_hash = scene_identity(scene.content_hash, config)
    run_id = new_run_id()
    attributes = {
        "reflect:technique": name,
        "reflect:parameters": params_json,
        "reflect:scene": config.scene.name,
        "reflect:scene_hash": scene_hash,
        "reflect:version": versions()["reflect"],
    }
    for index in selected:
        exr = os.path.join(folder, f"frame_{index:04d}.exr")
        if resume and os.path.exists(exr) and matches(
                stored.get(os.path.basename(exr)), scene_hash, json.loads(params_json)):
            if preview and not os.path.exists(exr[:-4] + ".png"):
                write_missing_preview(exr)
            result.skipped.append(index)
            continue
        camera = camera_from_config(config.camera, index)
        start = time.perf_counter()
        frame = tech.render(state, index, camera)
        render_seconds = time.perf_counter() - start
        row = {
            "scene": config.scene.name,
            "technique": name,
            "parameters": json.loads(params_json),
            "frame": index,
            "file": os.path.basename(exr),
            "frame_seconds": render_seconds,
            "prepare_seconds": prepare_seconds,
            "numba_compile_seconds": result.compile_seconds,
            "stages": frame.timings,
            **frame.stats,
            "threads": threads,
            "cpu": cpu_name(),
            "versions": versions(),
            "scene_hash": scene_hash,
            "run_id": run_id,
            "overrides": list(overrides),
        }
        channels = frame_channels(frame)
        check_finite(channels, display, index)
        with interrupts_deferred():  # a frame is kept with its log line, or not at all
            t1 = time.perf_counter()
            target = exr
            try:
                write_exr(exr, channels, {**attributes, "reflect:frame": str(index)})
                if preview:
                    target = exr[:-4] + ".png"
                    write_png(target, frame.rgb)
                target = log_path
                append_jsonl(log_path, {**row, "write_seconds": time.perf_counter() - t1})
            except OSError as e:
                discard(exr, *([exr[:-4] + ".png"] if preview else []))
                raise write_failure(e, target) from None
            result.written.append(exr)  # counted before an interrupt held meanwhile is raised
            if on_frame is not None:
                on_frame(index, exr)
    return result


@dataclass
class PrecomputeResult:
    cache: str
    maps: list[dict] = field(default_factory=list)


def precompute(
    path: str,
    *,
    technique: str | None = None,
    overrides: tuple[str, ...] | list[str] = (),
    cache: str | None = None,
    threads: int | None = None,
    on_map: Callable[[dict], None] | None = None,
    on_progress: Callable[[int, int], None] | None = None,
) -> PrecomputeResult:
    """Capture (or find in the cache) every map the scene's technique needs."""
    import numba

    config, _ = load_config(path, overrides, technique)
    name = config.technique.name
    cls = TECHNIQUES[name]
    if not hasattr(cls, "precompute"):
        map_based = sorted(n for n, c in TECHNIQUES.items() if hasattr(c, "precompute"))
        raise Problems(
            [
                Problem(
                    "--technique" if technique else path,
                    "technique.name",
                    f"'{name}' uses no precomputed maps (map-based: {', '.join(map_based)})",
                )
            ]
        )
    folder = cache if cache is not None else default_cache_dir(path)
    prepare_output(folder, "--cache" if cache is not None else path, "")
    scene = build_scene(config, path)
    if threads is not None:
        if not 1 <= threads <= numba.config.NUMBA_NUM_THREADS:
            raise Problems([Problem("--threads", "",
                                    f"must be 1..{numba.config.NUMBA_NUM_THREADS}")])
        numba.set_num_threads(threads)
    tech = cls(config.technique, numba.get_num_threads(), folder)
    result = PrecomputeResult(folder)
    result.maps = tech.precompute(scene, on_map, on_progress)
    return result


def clear_cache(folder: str) -> int:
    """Delete the maps in a cache folder; how many."""
    return MapCache(folder).clear()
