"""Frames written behind the renderer: same files as written in line, errors surface."""

from __future__ import annotations

import os

import pytest
from conftest import open_scene

from reflectcli import api
from reflectcli.output.log import read_jsonl

SMALL = ("camera.width=64", "camera.height=48", "camera.path.frames=4")


def _files(folder: str) -> dict[str, bytes]:
    return {n: open(os.path.join(folder, n), "rb").read()
            for n in sorted(os.listdir(folder)) if n.endswith((".exr", ".png"))}


def test_background_writes_equal_inline_writes(tmp_path):
    seen = []
    for background in (False, True):
        opened = open_scene("teapot-box", "raster", SMALL, threads=1)
        calls: list[int] = []
        result = opened.write_frames(opened.frames(), out=str(tmp_path / str(background)),
                                     preview=True, background=background,
                                     on_frame=lambda i, _: calls.append(i))
        assert calls == [0, 1, 2, 3] and len(result.written) == 4
        rows = read_jsonl(os.path.join(result.folder, "timings.jsonl"))
        assert [r["frame"] for r in rows] == [0, 1, 2, 3]
        seen.append(_files(result.folder))
    assert seen[0] == seen[1] and len(seen[0]) == 8


def test_writer_error_surfaces_and_keeps_written_frames(tmp_path, monkeypatch):
    real = api.write_exr_packed

    def failing(path, *args):
        if path.endswith("frame_0002.exr"):
            raise OSError("disk full (test)")
        real(path, *args)

    monkeypatch.setattr(api, "write_exr_packed", failing)
    opened = open_scene("teapot-box", "raster", SMALL, threads=1)
    calls: list[int] = []
    with pytest.raises(OSError, match="disk full"):
        opened.write_frames(opened.frames(), out=str(tmp_path),
                            on_frame=lambda i, _: calls.append(i))
    folder = os.path.join(str(tmp_path), opened.name, "raster")
    assert calls == [0, 1]
    assert sorted(n for n in os.listdir(folder) if not n.endswith(".jsonl")) == [
        "frame_0000.exr", "frame_0001.exr"]
    assert [r["frame"] for r in read_jsonl(os.path.join(folder, "timings.jsonl"))] == [0, 1]
