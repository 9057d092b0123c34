"""`cache clear` deletes only the files reflect itself writes in a cache folder (its maps and
the temporary files of killed captures) and says how many of each; a file at a map's name
that is no map of the shape looked up is reported, deleted and recaptured, its pixels never
read if its header claims more than that map holds."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner
from exr_headers import crafted_exr, header_only_exr, zero_exr

from reflectcli.cli import cli
from reflectcli.maps.cache import MapCache, MapShape

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
    path = MapCache(str(tmp_path)).path("envmap", KEY)
    os.mkfifo(path)
    code = ("import logging, sys\nfrom reflectcli.maps.cache import MapCache, MapShape\n"
            "logging.basicConfig(stream=sys.stderr, format='%(message)s')\n"
            f"print(MapCache({str(tmp_path)!r}).load('envmap', {KEY!r}, MapShape(6, 16, 3), "
            "lambda p: True))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60)
    assert done.stdout.strip() == "None", done.stderr
    assert "is damaged (not a regular file); recapturing" in done.stderr
    assert not os.path.lexists(path)  # removed: the capture's store takes the name


# Each planted file claims gigabytes in at most a few megabytes; the load runs in
# a child whose address space is limited to 1 GiB, so that reading the claim (a MemoryError
# traceback, or the machine's memory) fails the test rather than the machine; a real map
# (16 texels a side, the parts and channels looked up) then stored in its place loads under
# the same limit.
CHILD = """
import logging, resource, sys
import numpy as np
import OpenImageIO  # imported before the limit: its pools are no part of a read
from reflectcli.maps.cache import MapCache, MapShape
logging.basicConfig(stream=sys.stderr, format='%(message)s')
root, key, parts, side, channels = sys.argv[1], sys.argv[2], *map(int, sys.argv[3:])
shape = MapShape(parts, side, channels)
limit = 1 << 30
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
cache = MapCache(root)
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(cache.load('envmap', key, shape, lambda p: True))
print((resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) >> 10)  # MiB
names = 'RGBZS'[:channels]
real = [(f'p{i}', {n: np.full((16, 16), i, np.float32) for n in names}) for i in range(parts)]
cache.store('envmap', key, real, {})
print(len(cache.load('envmap', key, MapShape(parts, 16, channels), lambda p: True)))
"""


@pytest.mark.parametrize(("plant", "shape", "reason"), [
    # 60000 x 60000 x 3 floats (43 GB) from a 7 MB header (the file `compare` was given)
    (lambda p: header_only_exr(p, 60000, 60000), MapShape(6, 16, 3),
     "part 0: 60000x60000 pixels of 3 channels; the limit is 16 a side, 256 pixels, "
     "3 channels"),
    # the largest side a map may have, in 64 channels where 3 are looked up (4.3 GB)
    (lambda p: header_only_exr(p, 4096, 4096, channels=64, tile=16), MapShape(6, 4096, 3),
     "part 0: 4096x4096 pixels of 64 channels; the limit is 4096 a side, 16777216 pixels, "
     "3 channels"),
    # the map's own size, in one tile of 20000 x 20000 (4.8 GB) from 385 bytes
    (lambda p: crafted_exr(p, 16, 16, tile=(20000, 20000)), MapShape(6, 16, 3),
     "part 0: tiles of 20000x20000 pixels; the limit is 16 a side, 256 pixels"),
    # 64 parts of the map's own size, every pixel there (0.8 GB), where the map has 6
    (lambda p: zero_exr(p, 1024, 1024, parts=64), MapShape(6, 1024, 3),
     "part 6: more than the map's 6 part(s)"),
], ids=["side", "channels", "tiles", "parts"])
def test_a_header_claiming_more_than_the_map_is_refused_before_its_pixels(tmp_path, plant,
                                                                           shape, reason):
    path = MapCache(str(tmp_path)).path("envmap", KEY)
    plant(path)
    assert os.path.getsize(path) < 10 << 20
    done = subprocess.run([sys.executable, "-c", CHILD, str(tmp_path), KEY, *map(str, shape)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    loaded, grown, reloaded = done.stdout.split()
    assert loaded == "None"
    assert int(grown) < 64, f"the refused load grew the process by {grown} MiB"
    assert done.stderr == f"cache: {path} is damaged ({reason}); recapturing\n"
    assert reloaded == str(shape.parts)


def _noise_parts(parts: int, side: int) -> list:
    noise = np.random.default_rng(0).random((side, side), np.float32)  # zip keeps its size
    return [(f"p{i}", {c: noise + i for c in "RGB"}) for i in range(parts)]


def test_a_map_file_cut_short_after_every_write_reported_success_is_a_failed_store(
        tmp_path, monkeypatch):
    # the single-part writer checks the file's tail after close (a full disk at the last
    # flush lost it with every call reporting success); the map writer did not: the cache
    # kept a map that read back truncated. Here the tail is lost after a successful close.
    import OpenImageIO as oiio

    from reflectcli.output.failures import WriteFailed

    real = oiio.ImageOutput

    class ShortTail:
        def __init__(self, out):
            self.out = out

        def __getattr__(self, name):
            return getattr(self.out, name)

        def close(self):
            ok = self.out.close()
            with open(self.path, "r+b") as f:  # the tail the disk did not take
                f.truncate(os.path.getsize(self.path) * 3 // 4)
            return ok

    class LosingTail:
        @staticmethod
        def create(path):
            out = ShortTail(real.create(path))
            out.path = path
            return out

    cache = MapCache(str(tmp_path / "cache"))
    monkeypatch.setattr(oiio, "ImageOutput", LosingTail)
    with pytest.raises(WriteFailed, match="the file is shorter than what was written"):
        cache.store("envmap", KEY, _noise_parts(6, 24), {})
    assert os.listdir(tmp_path / "cache") == []  # neither the map nor its temporary file


def test_a_truncated_map_is_a_miss_recaptured_not_an_error(tmp_path, caplog):
    cache = MapCache(str(tmp_path))
    path = cache.store("envmap", KEY, _noise_parts(6, 24), {})
    with open(path, "r+b") as f:
        f.truncate(os.path.getsize(path) * 3 // 4)
    with caplog.at_level("WARNING", logger="reflect"):
        assert cache.load("envmap", KEY, MapShape(6, 24, 3), lambda p: True) is None
    assert f"cache: {path} is damaged (" in caplog.text and "recapturing" in caplog.text
    assert not os.path.lexists(path)  # the recapture's store takes the name
    cache.store("envmap", KEY, _noise_parts(6, 24), {})
    assert len(cache.load("envmap", KEY, MapShape(6, 24, 3), lambda p: True)) == 6
