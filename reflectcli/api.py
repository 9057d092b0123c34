"""The library face: open a scene file once, then list, render and write its frames.

    scene = api.open_scene("scenes/teapot-box.toml", technique="dprm", threads=2)
    frame = scene.render_frame(0)                          # a Frame in memory
    scene.write_frames(scene.frames("0:3"), out="out")     # EXR + preview + log row each

`render`, `precompute` and `compare` are what the CLI and the bench call; the tests and the
scripts in benchmarks/ open scenes the same way. Nothing else wires config -> scene ->
technique -> camera -> frame.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import re
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal, TypeVar

from pydantic import BaseModel

from . import heap, interrupts
from .camera import Camera, camera_from_config
from .config.memory import BYTES_PER_PIXEL
from .config.names import root_length_problem
from .config.scene import SceneConfig
from .errors import Problem, Problems
from .frame import Frame
from .loading import load_config
from .maps.cache import Cleared, MapCache, default_cache_dir
from .output.failures import write_failure
from .output.finite import check_finite
from .output.frame_writer import FrameFiles, FrameWriter, OnWritten
from .output.identity import (
    check_same_overrides,
    file_matches,
    logged_rows,
    matches,
    new_run_id,
    scene_identity,
)
from .output.lock import frame_folder_lock
from .output.names import SUMMARY_NAME
from .output.paths import (
    check_links,
    check_writable,
    inside,
    make_folder,
    prove_writable,
    remove_stale_temps,
)
from .output.png import write_png
from .output.summary import write_summary
from .provenance import cpu_name, versions
from .scene.build import build_scene, scene_hashes
from .scene.types import Scene
from .techniques import registry
from .techniques.base import MapTechnique, Technique

# --- the technique registry, as the api sees it (the only place it reads the registry) ------


def technique_class(name: str) -> type[Technique]:
    """The technique's class (its kernels are imported now, not before)."""
    return registry.technique_class(name)


def technique_names() -> list[str]:
    return sorted(registry.CLASSES)


def uses_maps(cls: type[Technique]) -> bool:
    """Whether a technique captures maps before rendering (`reflect precompute-maps`)."""
    return issubclass(cls, MapTechnique)


def check_technique(name: str | None) -> None:
    """--technique must name a registered technique (one Problem, before anything is read)."""
    if name is not None and name not in technique_names():
        raise Problems([Problem("--technique", "", f"unknown technique '{name}' "
                                f"(known: {', '.join(technique_names())})")])


def check_threads(threads: int | None) -> None:
    """--threads must be 1..the cores numba sees (one Problem, before anything is written)."""
    import numba

    if threads is not None and not 1 <= threads <= numba.config.NUMBA_NUM_THREADS:
        raise Problems([Problem("--threads", "", f"must be 1..{numba.config.NUMBA_NUM_THREADS}")])


# --- frames, folders, channels --------------------------------------------------------------


_FRAME_NUMBER = re.compile(r"-?[0-9]+")


def _frame_number(text: str) -> int:
    """A frame number as written in --frames: ASCII digits only (int() also took '1_0',
    ' 3 ' and other scripts' digits, '٣', and rendered frames nobody typed)."""
    if not _FRAME_NUMBER.fullmatch(text):
        raise ValueError(text)
    return int(text)


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
            stride = _frame_number(step[0]) if step and step[0] else 1
            if stride < 1:
                raise ValueError(spec)
            r = range(_frame_number(a) if a else 0,
                      min(_frame_number(b), count) if b else count, stride)
        else:
            r = range(_frame_number(spec), _frame_number(spec) + 1)
    except ValueError:
        message = f"expected N, A:B or A:B:S, got '{spec}'"
        raise Problems([Problem("--frames", "", message)]) from None
    if len(r) == 0 or r.start < 0 or r.stop > count:
        raise Problems([Problem("--frames", "", f"'{spec}' selects no frame of 0..{count - 1}")])
    return r


def check_output_root(root: str, source: str, field: str,
                      config: SceneConfig | None = None, technique: str | None = None) -> None:
    """An empty output folder name (`--out ''`, `output.dir = ""`) is refused by name: it
    would otherwise read as the working directory, or fail as a path written outside ''.
    With the scene's `config` (and the `technique` used), a root whose output paths the file
    system could not hold is refused too (config/names.py)."""
    if root == "":
        raise Problems([Problem(source, field, "empty folder name ('.' is the working "
                                "directory)")])
    if config is not None:
        why = root_length_problem(root, config.scene.name, technique or config.technique.name,
                                  config.output.log)
        if why is not None:
            raise Problems([Problem(source, field, why)])


def prepare_output(folder: str, source: str, field: str) -> None:
    """Create the frame folder and prove it writable before any rendering starts."""
    try:
        os.makedirs(folder, exist_ok=True)
        probe = os.path.join(folder, f".write-test-{os.getpid()}")
        with contextlib.suppress(FileNotFoundError):
            os.unlink(probe)  # a link left at the name would be written through
        with open(probe, "x"):
            pass
        os.unlink(probe)
    except OSError as e:
        raise Problems(
            [Problem(source, field, f"cannot write to '{folder}': {e.strerror}")]
        ) from None


def write_missing_preview(exr: str, width: int, height: int) -> bool:
    """--resume --preview: the PNG of a kept frame, from its EXR; False (nothing written)
    when the EXR is not readable as a `width` x `height` frame, which is then rendered
    again as any damaged frame is. Its header is checked before any pixel is read
    (output/exr.frame_problem: a planted header claiming 60000 x 60000 pixels was read), and
    its values must be finite (Z may be +inf), as every frame reflect writes is (OpenEXR
    reads a damaged zip chunk without an error: a preview was made of NaN pixels)."""
    import numpy as np

    from .output.exr import frame_problem, read_exr

    try:
        channels, _ = read_exr(exr, fits=lambda spec: frame_problem(spec, width, height))
    except OSError:
        return False
    try:
        check_finite(channels, exr, 0)  # what a frame's writer held it to (Z may be +inf)
    except Problems:
        return False
    write_png(exr[:-4] + ".png", np.stack([channels[c] for c in "RGB"], axis=-1))
    return True


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
    """Compile (or load from cache) the technique's numba kernels on a tiny scene; seconds
    (0 when this process already did it for these parameters)."""
    key = (technique_name, params_json)
    if key in _warmed:
        return 0.0
    from . import warmup

    start = time.perf_counter()
    with warmup.compile_notice(technique_name):
        scene, camera = warmup.warm_scene()
        cls = technique_class(technique_name)
        technique = cls(cls.Params.model_validate_json(warmup.warm_params(params_json)),
                        threads)
        logger = logging.getLogger("reflect")
        level = logger.level
        logger.setLevel(logging.ERROR)  # the warm-up scene's notices are nobody's business
        try:
            technique.render(technique.prepare(scene), 0, camera)
        finally:
            logger.setLevel(level)
    _warmed[key] = time.perf_counter() - start
    return _warmed[key]


# --- the opened scene -----------------------------------------------------------------------


@dataclass
class RenderResult:
    folder: str
    log: str = ""  # the frames' log (the scene's output.log inside the folder)
    written: list[str] = field(default_factory=list)
    skipped: list[int] = field(default_factory=list)
    compile_seconds: float = 0.0
    # the timings summary's warning (too few renders after the warm-up to quote), if any
    timing_warning: str = ""


class OpenedScene:
    """A scene file read once: overrides and technique applied.

    The scene is built, and the technique made (threads checked and set) and prepared, on
    first use: listing frames costs no build, and bad input is reported in a fixed order
    (frames, threads, what the build rejects, folders) before anything is written.
    """

    def __init__(self, config: SceneConfig, path: str, *, threads: int | None = None,
                 cache: str | None | Literal[False] = None,
                 technique_option: str | None = None,
                 overrides: tuple[str, ...] | list[str] = (),
                 provenance: dict | None = None) -> None:
        self.config = config
        self.provenance = provenance  # the file each field came from (load_config's)
        self.overrides = list(overrides)  # --set, recorded in the log rows
        self.path = path
        self.threads = threads  # asked for; None: numba's own count
        self.cache_option = cache  # as asked for, for the names in messages
        # where maps live: the folder given, .reflect-cache/ beside the scene, or memory only
        self.cache = default_cache_dir(path) if cache is None else (cache or None)
        self.technique_option = technique_option  # --technique, if it overrode the scene's
        self.compile_seconds = 0.0
        self.prepare_seconds = 0.0
        self._scene: Scene | None = None
        self._technique: Technique | None = None
        self._state: Any = None
        self._prepared = False
        self.run_id = new_run_id()  # one per opened scene: the log rows of one run

    # what the file says

    @property
    def name(self) -> str:
        return self.config.scene.name

    @property
    def technique_name(self) -> str:
        return self.config.technique.name

    @property
    def params(self) -> BaseModel:
        return self.config.technique

    @property
    def frame_count(self) -> int:
        return self.config.camera.frame_count

    def frames(self, spec: str | None = None) -> range:
        """The frame indices a `--frames` spec selects (all of them for None)."""
        return parse_frames(spec, self.frame_count)

    @property
    def display(self) -> str:
        """The scene file as messages name it."""
        rel = os.path.relpath(self.path)
        return self.path if rel.startswith("..") else rel

    @property
    def dir_source(self) -> str:
        """The file `output.dir` came from (an include, `--set`), as messages name it."""
        return self.source_of("output", "dir")

    def source_of(self, *loc) -> str:
        """The file the field at `loc` came from (an include, `--set`; else the scene)."""
        from .config.load import origin

        return origin(self.provenance or {}, loc, self.display)

    @property
    def scene_hash(self) -> str:
        """sha256 of the scene alone (its content, the files it reads, its name and camera;
        not the technique or the output section), so an image pairs with its reference."""
        content = (self._scene.content_hash if self._scene is not None
                   else scene_hashes(self.config, self.path)[1])
        return scene_identity(content, self.config)

    # what is built from it

    def build(self) -> Scene:
        """The flattened world-space arrays of every object and mirror, built once; raises
        Problems for what cannot be built (mesh files, degenerate mirrors)."""
        if self._scene is None:
            self._scene = build_scene(self.config, self.path, self.provenance)
        return self._scene

    @property
    def scene(self) -> Scene:
        return self.build()

    @property
    def technique(self) -> Technique:
        """The technique with the scene's parameters (numba's thread count set first)."""
        if self._technique is None:
            import numba

            check_threads(self.threads)
            # None is every core, whatever an earlier run in this process set
            numba.set_num_threads(self.threads if self.threads is not None
                                  else numba.config.NUMBA_NUM_THREADS)
            cls = technique_class(self.technique_name)
            self._technique = cls(self.params, numba.get_num_threads(), self.cache)
        return self._technique

    def camera(self, frame_index: int) -> Camera:
        """The camera of one frame of the path: world -> eye (view) -> clip (projection)."""
        return camera_from_config(self.config.camera, frame_index)

    def warm_up(self) -> float:
        """Compile the technique's kernels on a tiny scene, so compile time stays out of
        the frame timings; seconds."""
        self.compile_seconds = warm_up(self.technique_name, self.params.model_dump_json(),
                                       self.technique.threads)
        return self.compile_seconds

    def prepare(self) -> Any:
        """The technique's per-scene work (acceleration structures, maps) and the frames'
        working memory (heap.py), done once."""
        if not self._prepared:
            scene, technique = self.scene, self.technique
            start = time.perf_counter()
            self._state = technique.prepare(scene)
            technique.prepare_first_view(self._state, self.camera(0))
            # the frames' working memory faulted in once, here, not in frame 0's time
            camera = self.config.camera
            heap.reserve(camera.width * camera.height * BYTES_PER_PIXEL)
            self.prepare_seconds = time.perf_counter() - start
            self._prepared = True
        return self._state

    # the pipeline

    def render_frame(self, frame_index: int) -> Frame:
        """One frame of the camera path, rendered in memory (nothing is written)."""
        # the scene in world space, with the technique's per-scene work (accelerators, maps)
        state = self.prepare()
        # this frame's camera: world -> eye (view), eye -> clip (projection), NDC -> screen
        camera = self.camera(frame_index)
        # the technique: first hits and the mirrors' reflections, as screen-space buffers
        # (linear rgb, eye-space depth, surface ids, mirror mask)
        return self.technique.render(state, frame_index, camera)

    def check_output(self, out: str | None = None,
                     frames: range | list[int] | None = None,
                     hold: contextlib.ExitStack | None = None) -> str:
        """Every check render makes before it writes anything, after the scene file and
        --frames are read (open_render), in render's order: --threads, the scene build, the
        output root (--out or output.dir: empty, too long for the file system), the frame
        folder's path, the map cache folder, links and non-files at the names a render
        writes (`frames`: the frames to be written; paths.check_links), whether the frame
        folder can be made and written into, and frames of other --set overrides in it. The
        folder: <out or output.dir>/<scene>/<technique>/.

        Without `hold` (`reflect validate`) nothing is written: a folder is made and removed
        where the frame folder would go (paths.check_writable). With it (render), the frame
        folder is made, its lock entered into `hold`, and only then is it proven writable (a
        probe file, removed at once) and cleared of killed runs' temporary files: nothing
        lands in a folder another render is writing, and a render refused here leaves
        nothing but the folders it made for the lock."""
        check_threads(self.threads)  # before the build and the folder, as any bad argument
        self.build()  # the scene may still reject input before any folder is looked at
        root = out if out is not None else self.config.output.dir
        source, field = self.folder_source(out)
        check_output_root(root, source, field, self.config, self.technique_name)
        folder = inside(inside(root, self.name, self.display, "scene.name"),
                        self.technique_name, self.display)
        self.check_cache()
        check_links(root, folder, self.config.output.log, source, field,
                    self.source_of("output", "log"), frames)
        if hold is None:
            check_writable(folder, source, field)
        else:
            make_folder(folder, source, field)
            hold.enter_context(frame_folder_lock(folder, source, field))
            prove_writable(folder, source, field)
            remove_stale_temps(folder)
        self.check_overrides(folder)
        return folder

    def folder_source(self, out: str | None) -> tuple[str, str]:
        """Where the output folder came from, as messages name it: `--out`, or the file
        `output.dir` came from and the field."""
        return ("--out", "") if out is not None else (self.dir_source, "output.dir")

    def check_overrides(self, folder: str) -> dict[str, dict]:
        """The last log row of each frame in `folder`'s log, refused in one line if frames
        still there were rendered with other --set overrides than this run's."""
        stored = logged_rows(self.log_path(folder))
        check_same_overrides(stored, self.overrides, folder,
                             "--set" if self.overrides else self.display)
        return stored

    def check_cache(self) -> None:
        """A map technique's cache folder must be one it can make and write into: refused in
        one line before any folder is made, not a failed write after the output folder."""
        # an existing folder passes as it is: a complete cache may be read-only (maps are
        # written only on a miss, and such a write failing ends the run in one line)
        if (self.cache is not None and uses_maps(technique_class(self.technique_name))
                and not os.path.isdir(self.cache)):
            check_writable(self.cache, "--cache" if self.cache_option else self.display, "")

    def log_path(self, folder: str) -> str:
        """The folder's log (output.log), refused if it would leave the folder."""
        return inside(folder, self.config.output.log, self.source_of("output", "log"),
                      "output.log")

    def write_frame(self, frame_index: int, folder: str, *, preview: bool | None = None,
                    repeats: int = 1, on_written: OnWritten | None = None,
                    writer: FrameWriter | None = None) -> str:
        """Render a frame and write it into `folder`: EXR, optional PNG preview and its log
        row, all or nothing (Ctrl-C waits until the three are written). The EXR's path.

        `repeats` > 1 renders the frame that many times in a row (timing a scene of one frame:
        the bench's warm-up and timed samples); the first render is written and every
        render's seconds go to the log's `repeat_seconds`, its stages to `repeat_stages`
        (`stages` is the first render's). Techniques with temporal reuse see
        the repeats as extra frames. `on_written(exr, log row)` runs once the three are
        written, before an interrupt held meanwhile is raised (so a count of kept frames is
        exact). With an overlapping `writer` the files are written while the caller goes on
        (see write_frames); without one, before this returns."""
        exr = os.path.join(folder, f"frame_{frame_index:04d}.exr")
        self.prepare()
        start = time.perf_counter()
        frame = self.render_frame(frame_index)
        render_seconds = time.perf_counter() - start
        repeat_seconds = [render_seconds]
        repeat_stages = [frame.timings]  # each render's own stages, for the summary's spread
        for _ in range(repeats - 1):
            self.technique.forget_view(self._state)  # a repeat pays what a new view pays
            start = time.perf_counter()
            again = self.render_frame(frame_index)
            repeat_seconds.append(time.perf_counter() - start)
            repeat_stages.append(again.timings)
            del again
        overlapped = writer is not None and writer.overlap
        params = json.loads(self.params.model_dump_json())
        row = {
            "scene": self.name,
            "technique": self.technique_name,
            "parameters": params,
            "frame": frame_index,
            "file": os.path.basename(exr),
            "frame_seconds": render_seconds,
            "prepare_seconds": self.prepare_seconds,
            "numba_compile_seconds": self.compile_seconds,
            "stages": frame.timings,
            **frame.stats,
            "threads": self.technique.threads,
            "cpu": cpu_name(),
            "versions": versions(),
            "scene_hash": self.scene_hash,
            "run_id": self.run_id,
            "overrides": self.overrides,
            **({"repeat_seconds": repeat_seconds, "repeat_stages": repeat_stages}
               if repeats > 1 else {}),
            # the previous frame's files were being written (another thread) while this
            # frame rendered: its times include that competition for the cores
            **({"writes_overlapped": True} if overlapped else {}),
        }
        attributes = {
            "reflect:technique": self.technique_name,
            "reflect:parameters": self.params.model_dump_json(),
            "reflect:scene": self.name,
            "reflect:scene_hash": self.scene_hash,
            "reflect:version": versions()["reflect"],
            "reflect:frame": str(frame_index),
        }
        preview = self.config.output.preview if preview is None else preview
        channels = frame_channels(frame)
        check_finite(channels, self.display, frame_index)  # nothing non-finite is written
        files = FrameFiles.of(exr, channels, attributes, frame.rgb if preview else None,
                              self.log_path(folder), row)
        if writer is None:
            FrameWriter(overlap=False).submit(files, on_written)
        else:
            writer.submit(files, on_written)
        return exr

    def write_frames(self, frame_indices: range | list[int], *, out: str | None = None,
                     preview: bool | None = None, resume: bool = False,
                     on_frame: Callable[[int, str], None] | None = None,
                     repeats: int = 1, overlap_writes: bool = False) -> RenderResult:
        """Write the given frames into <out>/<scene>/<technique>/ (with `resume`, frames
        whose EXR exists and whose log row has this scene hash and these parameters are
        skipped, their missing previews written). A folder holding frames of other --set
        overrides is refused before anything is rendered.

        `overlap_writes` writes each frame's files on a background thread while the next
        frame renders (`reflect render` does; the bench does not, and repeats never do, so
        that their times are the render's alone). Rows rendered so are marked
        `writes_overlapped`."""
        with contextlib.ExitStack() as held:  # the frame folder's lock, taken by check_output
            result = RenderResult(self.check_output(out, frame_indices, hold=held))
            return self._write_frames_locked(result, frame_indices, preview=preview,
                                             resume=resume, on_frame=on_frame,
                                             repeats=repeats, overlap_writes=overlap_writes)

    def _write_frames_locked(self, result: RenderResult, frame_indices: range | list[int], *,
                             preview: bool | None, resume: bool,
                             on_frame: Callable[[int, str], None] | None, repeats: int,
                             overlap_writes: bool) -> RenderResult:
        """write_frames' work, with the frame folder held by this process alone."""
        result.log = self.log_path(result.folder)
        # the frames already there (check_output refused them if of other overrides, with the
        # folder held: no render can have added any since)
        stored = logged_rows(result.log)
        rows: list[dict] = []  # this call's log rows: the timings summary
        writer = FrameWriter(overlap=overlap_writes and repeats == 1)
        try:
            result.compile_seconds = self.warm_up()
            self.prepare()
            interrupts.check()  # a Ctrl-C a compile swallowed stops the run here
            wants_preview = self.config.output.preview if preview is None else preview
            params = json.loads(self.params.model_dump_json())
            defaults = json.loads(type(self.params)().model_dump_json())
            size = (self.config.camera.width, self.config.camera.height)  # a kept frame's
            for frame_index in frame_indices:
                interrupts.check()  # between frames, even if the interrupt was swallowed
                exr = os.path.join(result.folder, f"frame_{frame_index:04d}.exr")
                row = stored.get(os.path.basename(exr))
                if (resume and os.path.exists(exr)
                        and matches(row, self.scene_hash, params, defaults)
                        and file_matches(exr, row, defaults, size)
                        and (not wants_preview or os.path.exists(exr[:-4] + ".png")
                             or write_missing_preview(exr, *size))):
                    result.skipped.append(frame_index)
                    continue

                def kept(path: str, row: dict, frame_index: int = frame_index) -> None:
                    result.written.append(path)  # counted before an interrupt held meanwhile
                    rows.append(row)
                    if on_frame is not None:
                        on_frame(frame_index, path)

                self.write_frame(frame_index, result.folder, preview=preview, repeats=repeats,
                                 on_written=kept, writer=writer)
            writer.close()  # the last frame's files; a write failure is raised here
        except BaseException:
            # the frame in flight is kept (and counted) if its files were all written; a
            # failure of it is not what this run stops for, so it is not raised over the
            # error (or Ctrl-C) that is
            with interrupts.deferred(), contextlib.suppress(OSError):
                writer.close()
            raise
        finally:
            if rows:
                _write_run_summary(result, rows, stopping=sys.exc_info()[0] is not None)
        return result

    def precompute(self, on_map: Callable[[dict], None] | None = None,
                   on_progress: Callable[[int, int], None] | None = None) -> list[dict]:
        """Capture (or find in the cache) every map the technique needs; one record each."""
        if not uses_maps(technique_class(self.technique_name)):
            map_based = [n for n in technique_names() if uses_maps(technique_class(n))]
            raise Problems([Problem(
                "--technique" if self.technique_option else self.path, "technique.name",
                f"'{self.technique_name}' uses no precomputed maps "
                f"(map-based: {', '.join(map_based)})")])
        if self.cache is not None:
            prepare_output(self.cache, "--cache" if self.cache_option else self.path, "")
        scene = self.build()
        return self.technique.precompute(scene, on_map, on_progress)


def _write_run_summary(result: RenderResult, rows: list[dict], stopping: bool) -> None:
    """The run's timings summary beside its frames. A failure to write it is one line
    naming the file (WriteFailed, exit 1), never silent; unless the run is already stopping
    for another error or an interrupt, which is not hidden behind it."""
    path = os.path.join(result.folder, SUMMARY_NAME)
    with interrupts.deferred():
        try:
            summary = write_summary(path, rows)
        except OSError as e:
            if stopping:
                return
            raise write_failure(e, path) from None
    result.timing_warning = summary["warning"] if summary else ""


def open_scene(path: str, *, overrides: tuple[str, ...] | list[str] = (),
               technique: str | None = None, threads: int | None = None,
               cache: str | None | Literal[False] = None) -> OpenedScene:
    """Read and validate a scene file (technique and overrides applied).

    threads: numba's thread count for this scene's work (None: numba's own), checked when
    first needed. cache: the map folder (None: .reflect-cache/ beside the scene; False: maps
    in memory only). Raises Problems for bad input; nothing is built or written yet.
    """
    interrupts.requested.clear()  # a new run: earlier interrupts were answered
    config, provenance = load_config(path, overrides, technique)
    return OpenedScene(config, path, threads=threads, cache=cache, technique_option=technique,
                       overrides=overrides, provenance=provenance)


def open_render(path: str, *, frames: str | None = None, technique: str | None = None,
                overrides: tuple[str, ...] | list[str] = (), threads: int | None = None,
                cache: str | None = None) -> tuple[OpenedScene, range]:
    """`reflect render`'s arguments and scene file, checked in render's order before any
    folder is looked at: the --technique name (before the file is read), the scene with its
    overrides and technique, the --frames selection. The opened scene and its frames; the
    checks that follow are OpenedScene.check_output (validate) or write_frames (render)."""
    check_technique(technique)
    scene = open_scene(path, overrides=overrides, technique=technique, threads=threads,
                       cache=cache)
    return scene, scene.frames(frames)


def frames_past_end(spec: str | None, count: int) -> str | None:
    """`--frames A:B` with B past the path's end renders up to its end: the warning that
    says so (None when B is within the path)."""
    if spec and ":" in spec:
        end = spec.split(":")[1]
        if end.lstrip("-").isdigit() and int(end) > count:
            return (f"--frames: the camera path has {count} frame(s) (0..{count - 1}); "
                    f"rendering up to frame {count - 1}")
    return None


# --- what the CLI and the bench call --------------------------------------------------------


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
    cache: str | None = None,
    repeats: int = 1,
) -> RenderResult:
    """Render the selected frames of a scene file into out/<scene>/<technique>/.

    `repeats` > 1 renders each frame that many times in a row (for timing a scene of one
    frame: the bench's warm-up and timed samples); the first render is written and every
    render's seconds go to the log's `repeat_seconds`. Techniques with temporal reuse see
    the repeats as extra frames. Raises Problems for bad input before anything is written.
    """
    scene = open_scene(path, overrides=overrides, technique=technique, threads=threads,
                       cache=cache)
    return scene.write_frames(scene.frames(frames), out=out, preview=preview, resume=resume,
                              on_frame=on_frame, repeats=repeats)


@dataclass
class PrecomputeResult:
    cache: str | None  # None: maps kept in memory (cache=False)
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
    scene = open_scene(path, overrides=overrides, technique=technique, threads=threads,
                       cache=cache)
    return PrecomputeResult(scene.cache, scene.precompute(on_map, on_progress))


def clear_cache(folder: str) -> Cleared:
    """Delete the maps (and killed captures' temporary files) in a cache folder; how many."""
    return MapCache(folder).clear()


def compare(first: str, second: str, *, metrics: tuple[str, ...] | None = None,
            mask_channel: str | None = None, threshold: float = 0.1):
    """Score `second` against `first` (the reference EXR or PNG): every chosen metric over
    the whole image and, with `mask_channel`, over the pixels where it is > 0 in both; plus
    warnings (an sRGB PNG against a linear EXR, differing scenes or frames). Raises Problems
    naming the file."""
    from .metrics import DEFAULT_METRICS
    from .metrics.compare import compare_files

    return compare_files(first, second, metrics=metrics or DEFAULT_METRICS,
                         mask_channel=mask_channel, threshold=threshold)


M = TypeVar("M", bound=BaseModel)


def load_settings(path: str, model: type[M]) -> M:
    """A TOML settings file (a bench matrix) validated against `model`; Problems name the
    file and field."""
    from pydantic import ValidationError

    from .config.load import read_toml, validation_problems

    data = read_toml(path)
    try:
        return model.model_validate(data)
    except ValidationError as e:
        raise Problems(validation_problems(e, data, {}, os.path.relpath(path))) from None
