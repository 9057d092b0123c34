"""Two renders into one frame folder at once: the second stops in one line before it reads
the log or writes a file (both ran to the end, their log rows interleaved, each replacing
the frames the other was writing)."""

from __future__ import annotations

import multiprocessing
import os

from reflectcli.output.lock import frame_folder_lock

from .common import TINY, assert_one_line, chdir, invoke, write


def _hold(folder: str, ready, release) -> None:
    with frame_folder_lock(folder, "x"):
        ready.set()
        release.wait(30)


def test_a_second_render_into_a_folder_being_written_stops(tmp_path):
    scene = write(tmp_path, "s.toml", TINY)
    folder = tmp_path / "o" / "tiny" / "raytrace"
    folder.mkdir(parents=True)
    ready, release = multiprocessing.Event(), multiprocessing.Event()
    holder = multiprocessing.get_context("fork").Process(
        target=_hold, args=(str(folder), ready, release))
    holder.start()
    try:
        assert ready.wait(30)
        with chdir(tmp_path):
            result = invoke("render", scene, "--out", tmp_path / "o")
        assert_one_line(result, "--out:", "is being written by another render")
        assert os.listdir(folder) == []
    finally:
        release.set()
        holder.join(30)
    with chdir(tmp_path):  # once the first is done, the folder is free; no lock file is left
        assert invoke("render", scene, "--out", tmp_path / "o").exit_code == 0
    assert sorted(os.listdir(folder)) == ["frame_0000.exr", "timings.jsonl"]
