"""A rendered frame's files (EXR, optional PNG preview, log row), written all or nothing,
either at once or on one background thread while the next frame renders.

A frame is kept with its log line or not at all: the EXR and the preview are written under
temporary names, then the log row is appended, and only then are the two renamed into place.
If any of them fails, only the temporary files are removed: a frame written by an earlier
run stays whole with its own log row (a full disk on a re-render loses nothing), and the
failure names the file and the OS reason.
With `overlap`, at most one frame is in flight: submitting the next one first waits for it,
so log rows stay in frame order and a write failure stops the run one frame later at most.
The writer thread receives private copies of the pixels (the technique reuses its buffers).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..interrupts import deferred
from .atomic import atomic_path
from .exr import pack_channels, write_exr_at
from .failures import write_failure
from .log import append_jsonl, cut_back
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
    try:
        # temporary names until the row is logged; staged.close() renames them, preview first
        with contextlib.ExitStack() as staged:
            tmp = staged.enter_context(atomic_path(files.exr))
            write_exr_at(tmp, files.exr, files.channel_names, files.channel_data,
                         files.attributes)
            if files.preview_rgb is not None:
                target = files.png
                write_png_at(staged.enter_context(atomic_path(target)), target,
                             files.preview_rgb)
            target = files.log_path
            row = {**files.row, "write_seconds": time.perf_counter() - start}
            logged_at = append_jsonl(files.log_path, row)
            target = files.exr
            try:
                staged.close()  # the renames
            except OSError:
                cut_back(files.log_path, logged_at)  # no row for files not in place
                raise
    except OSError as e:
        raise write_failure(e, target) from None
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
