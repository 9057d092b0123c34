"""Two renders into one frame folder at once: the second stops in one line before it reads
the log or writes a file (both ran to the end, their log rows interleaved, each replacing
the frames the other was writing)."""

from __future__ import annotations

import errno
import os

from reflectcli.output.atomic import temporary_name
from reflectcli.output.lock import frame_folder_lock

from .common import TINY, assert_one_line, chdir, held_elsewhere, invoke, write

DEAD = 4_194_304  # above Linux's largest pid: no process has it


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


def test_a_refused_second_render_writes_nothing_in_the_folder_being_written(tmp_path,
                                                                             monkeypatch):
    # it made a probe folder (.reflect-validate-*) and a probe file (.write-test-<pid>) in
    # the frame folder, and cleared killed runs' files there, before it took the lock: a
    # removal that failed (EIO here) left its probe in the folder another render was writing
    scene = write(tmp_path, "s.toml", TINY)
    folder = tmp_path / "o" / "tiny" / "raytrace"
    folder.mkdir(parents=True)

    def refused_in(folder_path, real):
        def remove(path, *args, **kwargs):
            if os.path.dirname(os.path.abspath(path)) == str(folder_path):
                raise OSError(errno.EIO, os.strerror(errno.EIO), path)
            return real(path, *args, **kwargs)
        return remove

    with held_elsewhere(frame_folder_lock, folder), chdir(tmp_path):
        monkeypatch.setattr(os, "rmdir", refused_in(folder, os.rmdir))
        monkeypatch.setattr(os, "unlink", refused_in(folder, os.unlink))
        result = invoke("render", scene, "--out", tmp_path / "o")
    assert_one_line(result, "--out:", "is being written by another render")
    assert os.listdir(folder) == []


def test_render_probes_its_folder_once_it_holds_it(tmp_path):
    # the probe is one of atomic.py's temporary names: a run killed while it existed leaves
    # a file the next run removes as any killed run's temporary file
    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "raster"\n')
    folder = tmp_path / "o" / "tiny" / "raster"
    folder.mkdir(parents=True)
    probe = os.path.basename(temporary_name(str(folder / "write-test.json")))
    left = folder / probe.replace(f"tmp{os.getpid()}-", f"tmp{DEAD}-")
    left.write_bytes(b"")
    with chdir(tmp_path):
        result = invoke("render", scene, "--out", tmp_path / "o")
    assert result.exit_code == 0, result.output
    assert sorted(os.listdir(folder)) == ["frame_0000.exr", "timings.jsonl"]
