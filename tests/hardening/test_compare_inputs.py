"""`reflect compare`'s inputs: only regular files within the limits, each problem one line
naming the file (a named pipe hung the command for good, deaf to SIGTERM; a small EXR whose
header claims 60000 x 60000 pixels, or 64 x 64 in tiles of 20000 x 20000, was a MemoryError
traceback)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
from exr_headers import crafted_exr

from .common import assert_one_line, invoke


def _exr(path, width: int, height: int, tiled: bool = False) -> None:
    import OpenImageIO as oiio

    spec = oiio.ImageSpec(width, height, 3, oiio.HALF)
    out = oiio.ImageOutput.create(str(path))
    if tiled:  # no pixels written: the header alone claims the size
        spec.tile_width = spec.tile_height = 64
        out.open(str(path), spec)
    else:
        out.open(str(path), spec)
        out.write_image(np.zeros((height, width, 3), np.float32))
    out.close()


def test_a_named_pipe_is_refused_not_waited_on(tmp_path):
    _exr(tmp_path / "a.exr", 4, 4)
    os.mkfifo(tmp_path / "pipe")
    done = subprocess.run([sys.executable, "-m", "reflectcli.cli", "compare", "a.exr", "pipe"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip() == "pipe: not a regular file (a pipe, device or socket)"


def test_an_image_past_the_size_limit_is_one_line(tmp_path):
    _exr(tmp_path / "big.exr", 60000, 60000, tiled=True)
    assert os.path.getsize(tmp_path / "big.exr") < 64 << 20
    line = assert_one_line(invoke("compare", tmp_path / "big.exr", tmp_path / "big.exr"),
                           "big.exr: 60000x60000 pixels of 3 channels; the limit is 16384 a side")
    assert "Traceback" not in line


def test_an_image_in_tiles_past_the_size_limit_is_one_line(tmp_path):
    # 64 x 64 pixels in one tile of 20000 x 20000: 385 bytes, a MemoryError traceback
    crafted_exr(tmp_path / "tiles.exr", 64, 64, tile=(20000, 20000))
    line = assert_one_line(invoke("compare", tmp_path / "tiles.exr", tmp_path / "tiles.exr"),
                           "tiles.exr: tiles of 20000x20000 pixels; the limit is 16384 a side")
    assert "Traceback" not in line


def test_images_within_the_limits_compare(tmp_path):
    _exr(tmp_path / "a.exr", 8, 6)
    result = invoke("compare", tmp_path / "a.exr", tmp_path / "a.exr", "--metrics", "psnr")
    assert result.exit_code == 0, result.output
    assert "psnr" in result.output


def test_a_truncated_exr_is_one_line(tmp_path):
    # its header reads, its pixels do not: OpenImageIO's read_image gave None, and reshaping
    # it was a ValueError traceback
    from reflectcli.output.exr import write_exr

    noise = np.random.default_rng(0).random((48, 64), np.float32)
    write_exr(str(tmp_path / "a.exr"), {c: noise for c in "RGB"}, {})
    data = (tmp_path / "a.exr").read_bytes()
    (tmp_path / "cut.exr").write_bytes(data[: len(data) * 3 // 4])
    assert_one_line(invoke("compare", tmp_path / "a.exr", tmp_path / "cut.exr"),
                    "cut.exr: cannot read", "missing or corrupted")


def test_a_truncated_png_is_one_line_without_libpngs_own(tmp_path):
    # libpng writes "libpng error: ..." to the process's stderr itself before OpenImageIO
    # fails: a second line above reflect's (a subprocess, to see what reaches fd 2)
    from reflectcli.output.png import write_png

    write_png(str(tmp_path / "a.png"), np.random.default_rng(0).random((48, 64, 3), np.float32))
    data = (tmp_path / "a.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(data[: len(data) * 3 // 4])
    done = subprocess.run([sys.executable, "-m", "reflectcli.cli", "compare", "a.png", "cut.png"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert done.returncode == 2, done.stderr
    assert done.stdout == ""
    assert done.stderr.splitlines() == [
        "cut.png: cannot read cut.png: Read error: hit end of file in png reader"]
