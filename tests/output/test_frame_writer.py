"""Frames written behind the renderer (`reflect render`) are the frames written in place:
same bytes, same log rows in frame order, and a failure keeps every earlier frame whole."""

from __future__ import annotations

import errno
import json
import os
import threading

import numpy as np
import pytest
from conftest import open_scene
from hardening.test_faults import WALK, consistent

from reflectcli.output import atomic, frame_writer
from reflectcli.output.failures import WriteFailed
from reflectcli.output.frame_writer import FrameFiles, FrameWriter


def _scene(tmp_path):
    path = tmp_path / "walk.toml"
    path.write_text(WALK)
    return open_scene(path, threads=1)


def _rows(folder):
    with open(os.path.join(folder, "timings.jsonl")) as f:
        return [json.loads(line) for line in f]


def test_overlapped_writes_give_the_same_files_and_rows_in_order(tmp_path):
    scene = _scene(tmp_path)
    kept = []
    in_place = scene.write_frames(scene.frames(), out=str(tmp_path / "a"), preview=True)
    behind = scene.write_frames(scene.frames(), out=str(tmp_path / "b"), preview=True,
                                overlap_writes=True,
                                on_frame=lambda index, path: kept.append(index))
    assert kept == list(range(12))  # reported in order, each once its files are all written
    assert [os.path.basename(p) for p in behind.written] == \
        [os.path.basename(p) for p in in_place.written]
    for a, b in zip(in_place.written, behind.written, strict=True):
        with open(a, "rb") as fa, open(b, "rb") as fb:
            assert fa.read() == fb.read()
        assert os.path.exists(b[:-4] + ".png")
    rows_a, rows_b = _rows(in_place.folder), _rows(behind.folder)
    assert [r["file"] for r in rows_b] == [r["file"] for r in rows_a]
    assert all(r.get("writes_overlapped") for r in rows_b)
    assert not any("writes_overlapped" in r for r in rows_a)
    with open(os.path.join(behind.folder, "timings-summary.json")) as f:
        write = json.load(f)["write"]  # the writes behind the renderer are summarised too
    assert write is not None and 0 <= write["p25_ms"] <= write["median_ms"] <= write["p75_ms"]


def test_repeats_are_never_timed_against_a_write(tmp_path):
    scene = _scene(tmp_path)
    result = scene.write_frames(scene.frames("0:2"), out=str(tmp_path / "o"),
                                overlap_writes=True, repeats=2)
    assert not any("writes_overlapped" in r for r in _rows(result.folder))


def test_a_failed_write_behind_the_renderer_keeps_earlier_frames_whole(tmp_path, monkeypatch):
    scene = _scene(tmp_path)
    real = frame_writer.write_exr_at
    calls = {"n": 0}

    def failing(tmp, path, *args):
        calls["n"] += 1
        if calls["n"] == 4:  # the 4th frame's EXR: the disk is full
            raise OSError(28, "No space left on device")
        return real(tmp, path, *args)

    monkeypatch.setattr(frame_writer, "write_exr_at", failing)
    kept = []
    with pytest.raises(WriteFailed) as failure:
        scene.write_frames(scene.frames(), out=str(tmp_path / "o"), overlap_writes=True,
                           on_frame=lambda index, path: kept.append(index))
    folder = tmp_path / "o" / "tiny" / "raster"
    assert "frame_0003.exr" in str(failure.value)
    assert kept == [0, 1, 2]
    assert consistent(folder) == [f"frame_{i:04d}.exr" for i in range(3)]


def test_on_written_runs_in_the_submitting_thread_in_order(tmp_path, monkeypatch):
    written, threads = [], []
    monkeypatch.setattr(frame_writer, "write_frame_files",
                        lambda files: written.append(files.exr) or files.row)
    writer = FrameWriter(overlap=True)
    for i in range(5):
        files = FrameFiles.of(str(tmp_path / f"f{i}.exr"), {"R": np.zeros((2, 2))}, {},
                              None, str(tmp_path / "log"), {"frame": i})
        writer.submit(files, lambda exr, row: threads.append(
            (row["frame"], threading.current_thread() is threading.main_thread())))
    writer.close()
    assert written == [str(tmp_path / f"f{i}.exr") for i in range(5)]
    assert threads == [(i, True) for i in range(5)]


def _fail(monkeypatch, module, name):
    """`module.name` writes part of its file, then finds the disk full."""
    real = getattr(module, name)

    def failing(*args):
        if name.endswith("_at"):
            with open(args[0], "wb") as f:
                f.write(b"half a frame")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(module, name, failing)
    return real


@pytest.mark.parametrize(("module", "name", "named"), [
    (frame_writer, "write_exr_at", "frame_0001.exr"),
    (frame_writer, "write_png_at", "frame_0001.png"),
    (frame_writer, "append_jsonl", "timings.jsonl"),
    (atomic.os, "replace", "frame_0001.exr"),
])
def test_a_failed_rewrite_keeps_the_finished_frame_and_its_row(tmp_path, monkeypatch,
                                                               module, name, named):
    # a re-render on a full disk once deleted the finished frame it never replaced
    scene = _scene(tmp_path)
    first = scene.write_frames(scene.frames("0:2"), out=str(tmp_path / "o"), preview=True)
    folder = first.folder
    before = {n: (tmp_path / folder / n).read_bytes() for n in sorted(os.listdir(folder))}
    _fail(monkeypatch, module, name)
    with pytest.raises(WriteFailed) as failure:
        scene.write_frames(scene.frames("1:2"), out=str(tmp_path / "o"), preview=True)
    monkeypatch.undo()
    assert str(failure.value).endswith(f"{named}: cannot write (No space left on device)")
    assert {n: (tmp_path / folder / n).read_bytes() for n in sorted(os.listdir(folder))} \
        == before  # no temporary file left, the frames and their rows as they were
    assert consistent(folder) == ["frame_0000.exr", "frame_0001.exr"]


def test_a_row_is_logged_only_once_its_files_are_in_place(tmp_path, monkeypatch):
    # logged first, a run killed before the renames left a row naming the earlier file,
    # which --resume then took for the new frame
    exr, log = str(tmp_path / "frame_0000.exr"), str(tmp_path / "log")
    with open(exr, "wb") as f:
        f.write(b"an earlier frame")
    seen = []
    real = frame_writer.append_jsonl

    def spy(path, row):
        with open(exr, "rb") as f:
            seen.append(f.read() != b"an earlier frame")
        seen.append(sorted(n for n in os.listdir(tmp_path) if n.startswith(".")))
        real(path, row)

    monkeypatch.setattr(frame_writer, "append_jsonl", spy)
    frame_writer.write_frame_files(FrameFiles.of(exr, {"R": np.zeros((2, 2))}, {}, None, log,
                                                 {"frame": 0}))
    assert seen[0] is True  # the new EXR was in place when its row was appended
    assert [n for n in seen[1] if "earlier" not in n] == []  # no temporary file left then
    assert sorted(os.listdir(tmp_path)) == ["frame_0000.exr", "log"]  # nor afterwards
