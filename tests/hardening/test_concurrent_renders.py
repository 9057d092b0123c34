"""Two renders into one frame folder at once: the second stops in one line before it reads
the log or writes a file (both ran to the end, their log rows interleaved, each replacing
the frames the other was writing)."""

from __future__ import annotations

import os

from reflectcli.output.lock import frame_folder_lock

from .common import TINY, assert_one_line, chdir, held_elsewhere, invoke, write


def test_a_second_render_into_a_folder_being_written_stops(tmp_path):
    scene = write(tmp_path, "s.toml", TINY)
    folder = tmp_path / "o" / "tiny" / "raytrace"
    folder.mkdir(parents=True)
    with held_elsewhere(frame_folder_lock, folder), chdir(tmp_path):
        result = invoke("render", scene, "--out", tmp_path / "o")
    assert_one_line(result, "--out:", "is being written by another render")
    assert os.listdir(folder) == []
    with chdir(tmp_path):  # once the first is done, the folder is free; no lock file is left
        assert invoke("render", scene, "--out", tmp_path / "o").exit_code == 0
    assert sorted(os.listdir(folder)) == ["frame_0000.exr", "timings.jsonl"]
