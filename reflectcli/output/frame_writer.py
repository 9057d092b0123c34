"""A rendered frame's files (EXR, optional PNG preview, log row), each written whole,
either at once or on one background thread while the next frame renders.

A frame is kept with its log line or not at all: the EXR and the preview are written under
temporary names, renamed into place (the EXR first; a file an earlier run left there is kept
under a second name meanwhile), then the log row is appended. If any step fails, the
temporary files are removed and the earlier files put back, so a frame an earlier run
finished stays whole with its own row (a full disk on a re-render loses nothing), and the
failure names the file and the OS reason. A row never describes files that are not there:
a run killed between the renames and the append leaves the new files with the earlier row
(or none), and `--resume` renders that frame again unless that row matches.
With `overlap`, at most one frame is in flight: submitting the next one first waits for it,
so log rows stay in frame order and a write failure stops the run one frame later at most.
The writer thread receives private copies of the pixels (the technique reuses its buffers).
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..interrupts import deferred
from .atomic import drop_aside, put_back, set_aside, temporary_path
from .exr import pack_channels, write_exr_at
from .failures import WriteFailed, write_failure
from .log import append_jsonl
from .png import write_png_at


@dataclass
class FrameFiles:
    """Everything one frame writes, detached from the renderer's buffers."""

    exr: str
    channel_names: list[str]
    channel_data: np.ndarray  # (H, W, C) float32, a private copy
    attributes: dict[str, str]
    preview_rgb: np.ndarray | None  # (H, W, 3) linear RGB, a private copy; None: no preview
    log_path: str
    row: dict  # the log row, without write_seconds (added when written)

    @classmethod
    def of(cls, exr: str, channels: dict[str, np.ndarray], attributes: dict[str, str],
           preview_rgb: np.ndarray | None, log_path: str, row: dict) -> FrameFiles:
        names, data = pack_channels(channels)  # a fresh copy
        preview = None if preview_rgb is None else np.array(preview_rgb, copy=True)
        return cls(exr, names, data, attributes, preview, log_path, row)

    @property
    def png(self) -> str:
        return self.exr[:-4] + ".png"


def write_frame_files(files: FrameFiles) -> dict:
    """EXR, preview, log row; returns the row as logged (with its write_seconds). On an
    OSError a WriteFailed naming the file being written is raised, and the files a previous
    run left under these names are as they were."""
    start = time.perf_counter()
    target = files.exr
    placed: list[tuple[str, str | None]] = []  # (path, its earlier file's second name)
    try:
        with contextlib.ExitStack() as stack:
            exr_tmp = stack.enter_context(temporary_path(files.exr))
            write_exr_at(exr_tmp, files.exr, files.channel_names, files.channel_data,
                         files.attributes)
            staged = [(exr_tmp, files.exr)]
            if files.preview_rgb is not None:
                target = files.png
                png_tmp = stack.enter_context(temporary_path(files.png))
                write_png_at(png_tmp, target, files.preview_rgb)
                staged.append((png_tmp, files.png))
            for tmp, path in staged:  # the EXR first
                target = path
                aside = set_aside(path)
                try:
                    os.replace(tmp, path)  # replaces a link at `path`; never writes through it
                except OSError:
                    drop_aside(aside)  # the earlier file is still in place
                    raise
                placed.append((path, aside))
        target = files.log_path
        # the EXR's size: --resume keeps a frame only if its file is still the one logged
        row = {**files.row, "write_seconds": time.perf_counter() - start,
               "exr_bytes": os.path.getsize(files.exr)}
        append_jsonl(files.log_path, row)
    except OSError as e:  # a WriteFailed too
        for path, aside in reversed(placed):
            put_back(path, aside)
        if isinstance(e, WriteFailed):
            raise
        raise write_failure(e, target) from None
    for _, aside in placed:  # the frame is whole: the earlier files' second names go
        drop_aside(aside)
    return row


OnWritten = Callable[[str, dict], None]


class FrameWriter:
    """Writes frames in submission order; with `overlap`, behind the renderer.

    `on_written(exr, row)` runs in the calling thread once a frame's files are all written,
    with Ctrl-C held, so a count of kept frames is exact; `row` is the log row as written,
    with its write_seconds (the run's timings summary reads them)."""

    def __init__(self, overlap: bool) -> None:
        self.overlap = overlap
        self._pool = (ThreadPoolExecutor(1, thread_name_prefix="reflect-writer")
                      if overlap else None)
        self._pending: tuple[Future, FrameFiles, OnWritten | None] | None = None

    def submit(self, files: FrameFiles, on_written: OnWritten | None = None) -> None:
        if self._pool is None:
            with deferred():  # a frame is kept with its log line, or not at all
                row = write_frame_files(files)
                if on_written is not None:
                    on_written(files.exr, row)
            return
        self.drain()
        self._pending = (self._pool.submit(write_frame_files, files), files, on_written)

    def drain(self) -> None:
        """Wait for the frame in flight; raises its write failure."""
        if self._pending is None:
            return
        future, files, on_written = self._pending
        with deferred():
            self._pending = None
            row = future.result()
            if on_written is not None:
                on_written(files.exr, row)

    def close(self) -> None:
        """Wait for the frame in flight (its failure is raised) and stop the thread."""
        try:
            self.drain()
        finally:
            if self._pool is not None:
                self._pool.shutdown(wait=True)
