"""remove_stale_temps deletes the temporary files of killed runs (named as atomic.py names
them) and nothing else in an output folder."""

from __future__ import annotations

import os

from reflectcli.output.atomic import atomic_path
from reflectcli.output.paths import TEMP, remove_stale_temps

DEAD = 4_194_304  # above Linux's largest pid: no process has it


def test_only_reflects_temporary_names_of_dead_processes(tmp_path):
    stale = [f".frame_0003.tmp{DEAD}-12.exr", f".frame_0003.tmp{DEAD}-12.png",
             f".timings-summary.tmp{DEAD}-7.json", f".results.tmp{DEAD}-7.csv",
             f".report.tmp{DEAD}-7.md"]
    users = [".notes.tmp99999", f".report.append{DEAD}.txt", f".notes.tmp{DEAD}",
             f".notes.tmp{DEAD}-1.exr.bak", f"frame.tmp{DEAD}-1.exr", f".x.tmp{DEAD}-1.exe",
             f".frame_0004.tmp{os.getpid()}-12.exr"]  # the last: a running process's
    for name in stale + users:
        (tmp_path / name).write_bytes(b"x")
    assert sorted(remove_stale_temps(str(tmp_path))) == sorted(stale)
    assert sorted(os.listdir(tmp_path)) == sorted(users)


def test_the_pattern_matches_what_atomic_path_names(tmp_path):
    for name in ("frame_0000.exr", "frame_0000.png", "timings-summary.json", "report.md",
                 "results.csv", f"envmap-{'a' * 32}.exr"):
        with atomic_path(str(tmp_path / name)) as tmp:
            open(tmp, "w").close()
            assert TEMP.match(os.path.basename(tmp)), tmp
