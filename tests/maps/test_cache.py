"""`cache clear` deletes only the files reflect itself writes in a cache folder (its maps and
the temporary files of killed captures) and says how many of each."""

from __future__ import annotations

import os

from click.testing import CliRunner

from reflectcli.cli import cli
from reflectcli.maps.cache import MapCache

KEY = "0123456789abcdef" * 2
DEAD = 4_194_304  # above Linux's largest pid: no process has it
MAPS = [f"envmap-{KEY}.exr", f"dprm-{'a' * 32}.exr", f"distmap-{KEY}.exr"]
# a user's files, some named almost as reflect's temporary files are
USERS = [".notes.tmp99999", f".report.append{DEAD}.txt", f".notes.tmp{DEAD}-1",
         f".frame_0000.tmp{DEAD}-1.exr", f".envmap-{KEY}.tmp{DEAD}-1.txt",
         f".envmap-{KEY}.tmp{DEAD}.exr", f"envmap-{KEY}.exr.bak", f"ENVMAP-{KEY}.exr",
         "envmap-short.exr", "timings.jsonl"]


def test_clear_deletes_reflects_files_only_and_counts_them(tmp_path):
    cache = tmp_path / "cache"
    cache.mkdir()
    stale = f".dprm-{KEY}.tmp{DEAD}-140234.exr"  # a killed capture's temporary file
    live = f".envmap-{KEY}.tmp{os.getpid()}-1.exr"  # a capture under way: kept
    for name in MAPS + USERS + [stale, live]:
        (cache / name).write_bytes(b"x")
    result = CliRunner().invoke(cli, ["cache", "clear", "--cache", str(cache)])
    assert result.exit_code == 0, result.output
    assert result.output == (f"removed 3 map(s) and 1 temporary file(s) of killed captures "
                             f"from {cache}\n")
    assert sorted(os.listdir(cache)) == sorted(USERS + [live])


def test_clear_of_a_folder_without_maps(tmp_path):
    (tmp_path / ".notes.tmp99999").write_bytes(b"x")
    assert MapCache(str(tmp_path)).clear() == (0, 0)
    assert MapCache(str(tmp_path / "absent")).clear() == (0, 0)
    assert os.listdir(tmp_path) == [".notes.tmp99999"]


def test_a_named_pipe_at_a_maps_name_is_recaptured_not_waited_on(tmp_path):
    # OpenImageIO's open of a pipe blocked the render for good, deaf to SIGTERM: the load runs
    # in a child process, killed if it waits, so that a regression fails rather than hangs
    import subprocess
    import sys

    path = MapCache(str(tmp_path)).path("envmap", KEY)
    os.mkfifo(path)
    code = ("import logging, sys\nfrom reflectcli.maps.cache import MapCache\n"
            "logging.basicConfig(stream=sys.stderr, format='%(message)s')\n"
            f"print(MapCache({str(tmp_path)!r}).load('envmap', {KEY!r}, lambda p: True))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60)
    assert done.stdout.strip() == "None", done.stderr
    assert "is damaged (not a regular file); recapturing" in done.stderr
    assert not os.path.lexists(path)  # removed: the capture's store takes the name
