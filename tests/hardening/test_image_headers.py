"""Image files reflect reads that a user can put in its way, held to their headers' claims
before any pixel is read: a texture (channels, texels times channels, tiles, deep data
besides its side and texels) is one line naming the scene file and the material's field from
`validate` and `render`; a kept frame `render --resume --preview` reads to make its missing
preview must be a frame of the camera's size, or it is rendered again as a damaged frame is.
Each planted file is at most a few megabytes and claims gigabytes."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from exr_headers import crafted_exr, header_only_exr

from reflectcli.output.exr import read_exr
from reflectcli.output.log import read_jsonl

from .common import TINY, chdir, check_bad, invoke, write

TEXTURED = TINY.replace('kind = "solid"\ncolor = [0.8, 0.1, 0.1]',
                        'kind = "texture"\npath = "t.EXT"\nsrgb = false')


def _many_channels_tiff(path, side: int = 1024, channels: int = 1000) -> None:
    """A zip-compressed TIFF of `side` x `side` zeros in `channels` 8-bit channels (1 MB for
    4 GB as float), written a row at a time. OpenImageIO opens at most 1024 channels."""
    import OpenImageIO as oiio

    spec = oiio.ImageSpec(side, side, channels, oiio.UINT8)
    spec.attribute("compression", "zip")
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec), oiio.geterror()
    row = np.zeros((side, channels), np.uint8)
    for y in range(side):
        assert out.write_scanline(y, 0, row), out.geterror()
    assert out.close(), oiio.geterror()


def _deep_exr(path) -> None:
    import OpenImageIO as oiio

    spec = oiio.ImageSpec(4, 4, 4, oiio.FLOAT)
    spec.channelnames = ("R", "G", "B", "A")
    spec.deep = True
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec), oiio.geterror()
    deep = oiio.DeepData()
    deep.init(spec)
    for pixel in range(16):
        deep.set_samples(pixel, 1)
    assert out.write_deep_image(deep), out.geterror()
    assert out.close(), oiio.geterror()


# the file's claim is read as the code before this change read it (every channel of the
# first part as float), then as load_texture reads it, in a child whose address space is
# limited to 1 GiB, so that reading a claim fails the child, not the machine
CHILD = """
import resource, sys
import OpenImageIO as oiio  # imported before the limit: its pools are no part of a read
from reflectcli.scene.textures import load_texture
limit = 1 << 30
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
inp = oiio.ImageInput.open(sys.argv[1])
try:
    inp.read_image(0, 0, 0, inp.spec().nchannels, oiio.FLOAT)
    print('read')
except MemoryError:
    print('MemoryError')
finally:
    inp.close()
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
try:
    load_texture(sys.argv[1], False)
    print('loaded')
except ValueError as e:
    print(e)
print((resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) >> 10)  # MiB
"""


@pytest.mark.parametrize(("ext", "plant", "reason"), [
    # 1024 x 1024 texels of 1000 channels (4 GB as float) in a 1 MB TIFF
    ("tif", _many_channels_tiff,
     "texture has 1024x1024 texels of 1000 channels; the limit is 16384 a side, 67108864 "
     "texels, 64 channels"),
    # 4096 x 4096 texels (within the side and texel limits) of 64 channels: 1G values
    ("exr", lambda p: header_only_exr(p, 4096, 4096, channels=64, tile=16),
     "texture has 4096x4096 texels of 64 channels, 1073741824 values; the limit is "
     "268435456 values (texels times channels)"),
    # 16 x 16 texels in one tile of 20000 x 20000 (4.8 GB) from 385 bytes
    ("exr", lambda p: crafted_exr(p, 16, 16, tile=(20000, 20000)),
     "texture has tiles of 20000x20000 texels; the limit is 16384 a side, 67108864 texels"),
    # 8 x 8 texels of 32 channels, in one tile of 8192 x 8192 (within the texel limit): 2G
    # values read for one tile
    ("exr", lambda p: crafted_exr(p, 8, 8, tile=(8192, 8192),
                                  channels="".join(chr(65 + i) for i in range(26)) + "abcdef"),
     "texture has tiles of 8192x8192 texels of 32 channels; the limit is 268435456 values "
     "(texels times channels)"),
], ids=["channels", "values", "tiles", "tile-values"])
def test_a_texture_header_claiming_too_much_is_one_line_before_its_pixels(tmp_path, ext,
                                                                          plant, reason):
    texture = tmp_path / f"t.{ext}"
    plant(texture)
    assert os.path.getsize(texture) < 2 << 20
    done = subprocess.run([sys.executable, "-c", CHILD, str(texture)], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    old, refused, grown = done.stdout.splitlines()
    assert old == "MemoryError"  # the read before this change
    assert refused == reason
    assert int(grown) < 64, f"the refused load grew the process by {grown} MiB"
    scene = write(tmp_path, "s.toml", TEXTURED.replace("EXT", ext))
    with chdir(tmp_path):
        check_bad(scene, f"s.toml: materials.red.path: {reason}")


def test_a_deep_texture_is_one_line(tmp_path):
    # read as flat texels it was garbage ("texture has texels past +-1e+09", or none)
    _deep_exr(tmp_path / "t.exr")
    scene = write(tmp_path, "s.toml", TEXTURED.replace("EXT", "exr"))
    with chdir(tmp_path):
        check_bad(scene, "s.toml: materials.red.path: texture has deep data (per-pixel "
                  "samples), which reflect does not read")


@pytest.mark.parametrize(("names", "expected"), [
    (("Y",), [0.25, 0.25, 0.25]),
    (("Y", "A"), [0.25, 0.25, 0.25]),
    (("R", "G", "B"), [0.25, 0.5, 0.75]),
    (("R", "G", "B", "A"), [0.25, 0.5, 0.75]),
    (("R", "G", "B", "A", "Z", "extra"), [0.25, 0.5, 0.75]),
])
def test_a_texture_reads_only_the_channels_it_uses(tmp_path, names, expected):
    import OpenImageIO as oiio

    from reflectcli.scene.textures import load_texture

    path = str(tmp_path / "t.exr")
    spec = oiio.ImageSpec(3, 2, len(names), oiio.FLOAT)
    spec.channelnames = names
    pixels = np.empty((2, 3, len(names)), np.float32)
    pixels[...] = [0.25, 0.5, 0.75, 1.0, 7.0, 9.0][:len(names)]
    out = oiio.ImageOutput.create(path)
    assert out.open(path, spec) and out.write_image(pixels) and out.close()
    texels = load_texture(path, srgb=False)
    assert texels.shape == (2, 3, 3)
    assert (texels == np.array(expected, np.float32)).all()


WALK = TINY.replace("height = 12\n", "height = 12\n[camera.path]\nframes = 2\n"
                    "keys = [{ eye = [0.0, 1.0, 3.0], target = [0.0, 0.5, 0.0] },\n"
                    "        { eye = [1.0, 1.0, 3.0], target = [0.0, 0.5, 0.0] }]\n")


def _plant(folder, plant) -> None:
    """Frame 1 replaced by `plant(path, attributes)`, a file carrying the frame's own
    reflect:* attributes, and its log row's size made the planted file's (a planted frame
    with its row, or a damaged frame that kept its size), its preview removed."""
    exr = folder / "frame_0001.exr"
    _, attrs = read_exr(str(exr))
    plant(exr, {k: v for k, v in attrs.items() if k.startswith("reflect:")})
    (folder / "frame_0001.png").unlink()
    log = folder / "timings.jsonl"
    rows = read_jsonl(str(log))
    for row in rows:
        if row["file"] == exr.name:
            row["exr_bytes"] = os.path.getsize(exr)
    log.write_text("".join(json.dumps(row) + "\n" for row in rows))


def _frame(path, attributes, width=16, height=12, names=("R", "G", "B", "A", "Z", "mirror"),
           noise: bool = False):
    import OpenImageIO as oiio

    spec = oiio.ImageSpec(width, height, len(names), oiio.FLOAT)
    spec.channelnames = names
    spec.attribute("compression", "zip")
    for key, value in attributes.items():
        spec.attribute(key, value)
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec)
    pixels = np.zeros((height, width, len(names)), np.float32)
    if noise:  # incompressible: the pixel data is most of the file
        pixels[...] = np.random.default_rng(0).random(pixels.shape)
    assert out.write_image(pixels) and out.close()


def _damaged_pixels(path, attributes) -> None:
    _frame(path, attributes, noise=True)  # zip-compressed: its last bytes (pixels) changed
    data = bytearray(path.read_bytes())
    data[-64:] = b"\xff" * 64
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("plant", [
    # 60000 x 60000 pixels (43 GB as float) in a 7 MB file with the frame's attributes
    lambda p, a: header_only_exr(p, 60000, 60000, attributes=a),
    # the camera's 16 x 12 pixels in one tile of 20000 x 20000 (4.8 GB)
    lambda p, a: crafted_exr(p, 16, 12, tile=(20000, 20000), attributes=a),
    # the camera's size in 64 channels
    lambda p, a: _frame(p, a, names=tuple(f"c{i}" for i in range(64))),
    # another size, or no R G B: no frame of this camera
    lambda p, a: _frame(p, a, width=12, height=16),
    lambda p, a: _frame(p, a, names=("Y", "A", "Z")),
    # the right header, damaged pixels: OpenEXR reads them without an error, 16 of them
    # NaN (a preview was made of them)
    _damaged_pixels,
], ids=["side", "tiles", "channels", "size", "no-rgb", "pixels"])
def test_resume_preview_renders_a_kept_frame_again_if_it_is_no_frame_of_the_camera(
        tmp_path, plant):
    scene = write(tmp_path, "s.toml", WALK)
    folder = tmp_path / "o" / "tiny" / "raytrace"
    with chdir(tmp_path):
        result = invoke("render", scene, "--out", tmp_path / "o", "--preview")
        assert result.exit_code == 0, result.output
        whole = (folder / "frame_0001.exr").read_bytes()
        _plant(folder, plant)
        result = invoke("render", scene, "--out", tmp_path / "o", "--resume", "--preview")
    assert result.exit_code == 0, result.output
    assert "wrote 1 frame(s)" in result.output and "1 skipped" in result.output
    assert (folder / "frame_0001.exr").read_bytes() == whole  # rendered again
    assert (folder / "frame_0001.png").is_file()


def test_resume_without_preview_renders_a_frame_of_another_size_again(tmp_path):
    # its pixels are not read without --preview, but it is no frame of this camera either
    scene = write(tmp_path, "s.toml", WALK)
    folder = tmp_path / "o" / "tiny" / "raytrace"
    with chdir(tmp_path):
        assert invoke("render", scene, "--out", tmp_path / "o").exit_code == 0
        whole = (folder / "frame_0001.exr").read_bytes()
        (folder / "frame_0001.png").touch()  # _plant removes it
        _plant(folder, lambda p, a: _frame(p, a, width=12, height=16))
        result = invoke("render", scene, "--out", tmp_path / "o", "--resume")
    assert result.exit_code == 0, result.output
    assert "wrote 1 frame(s)" in result.output and "1 skipped" in result.output
    assert (folder / "frame_0001.exr").read_bytes() == whole


def test_a_bench_contact_sheet_bounds_the_frames_it_reads(tmp_path, caplog):
    # rows of an earlier bench (--resume) name frames that may have been replaced since:
    # a header claiming more than a frame is refused before any pixel is read, and that
    # run's line of the sheet is left blank with a warning naming the file
    pytest.importorskip("matplotlib")
    from reflectcli.bench import plots

    scene = write(tmp_path, "s.toml", TINY)
    with chdir(tmp_path):
        assert invoke("render", scene, "--out", tmp_path / "o").exit_code == 0
    frame = str(tmp_path / "o" / "tiny" / "raytrace" / "frame_0000.exr")
    planted = tmp_path / "p.exr"
    header_only_exr(planted, 60000, 60000)  # 7 MB claiming 43 GB as float
    sheet = tmp_path / "sheet.png"
    for row, limit in (
            ({"images": [str(planted)], "reference_images": [frame]},
             "the limit is 16 a side, 192 pixels, 16 channels"),  # the reference's 16 x 12
            ({"images": [frame], "reference_images": [str(planted)]},  # a reference: a
             "the limit is 16384 a side, 67108864 pixels, 16 channels")):  # frame's limits
        caplog.clear()
        with caplog.at_level("WARNING", logger="reflect"):
            plots._contact_sheet([row], str(sheet))
        (warned,) = [r.getMessage() for r in caplog.records]
        assert f"sheet.png: {planted}: unreadable (60000x60000 pixels of 3 channels; " \
               f"{limit})" in warned
        assert sheet.exists()
        sheet.unlink()
