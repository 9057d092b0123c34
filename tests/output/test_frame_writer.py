"""Frames written behind the renderer (`reflect render`) are the frames written in place:
same bytes, same log rows in frame order, and a failure keeps every earlier frame whole."""

from __future__ import annotations

import json
import os
import threading

import numpy as np
import pytest
from conftest import open_scene
from hardening.test_faults import WALK, consistent

from reflectcli.output import frame_writer
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
    real = frame_writer.write_exr_packed
    calls = {"n": 0}

    def failing(path, *args):
        calls["n"] += 1
        if calls["n"] == 4:  # the 4th frame's EXR: the disk is full
            raise OSError(28, "No space left on device")
        return real(path, *args)

    monkeypatch.setattr(frame_writer, "write_exr_packed", failing)
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
