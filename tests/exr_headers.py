"""EXR files whose header claims more than the file holds, for the tests that hold a reader
to the header's claims before it reads pixels (OpenImageIO refuses to write some of these:
`crafted_exr` writes the bytes itself)."""

from __future__ import annotations

import struct

import numpy as np


def header_only_exr(path, width: int, height: int, channels: int = 3, parts: int = 1,
                    tile: int = 64, attributes: dict[str, str] | None = None) -> None:
    """A tiled EXR (`tile` x `tile` tiles) of `parts` parts, each `width` x `height` pixels of
    `channels` half channels, and no tile written: the headers alone claim the size.
    OpenImageIO 3.2 refuses to open a file whose claim is too many times its size (2 GB from
    133 kB): smaller tiles make a longer table of tile offsets, a larger file. `attributes`:
    string attributes of every part's header (a frame's reflect:scene_hash, ...)."""
    import OpenImageIO as oiio

    specs = []
    for index in range(parts):
        spec = oiio.ImageSpec(width, height, channels, oiio.HALF)
        spec.tile_width = spec.tile_height = tile
        spec.attribute("oiio:subimagename", f"part{index}")
        for key, value in (attributes or {}).items():
            spec.attribute(key, value)
        specs.append(spec)
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), specs), oiio.geterror()
    assert out.close(), oiio.geterror()


def zero_exr(path, width: int, height: int, channels: int = 3, parts: int = 1) -> None:
    """A whole EXR of `parts` parts, each `width` x `height` zeros in `channels` half
    channels, run-length encoded: a file of about 2 bytes in 1000 of what reading it takes
    as float (64 parts of 1024 x 1024 x 3: 7.8 MB, 0.8 GB read)."""
    import OpenImageIO as oiio

    specs = []
    for index in range(parts):
        spec = oiio.ImageSpec(width, height, channels, oiio.HALF)
        spec.attribute("compression", "rle")
        spec.attribute("oiio:subimagename", f"part{index}")
        specs.append(spec)
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), specs), oiio.geterror()
    zeros = np.zeros((height, width, channels), np.float16)
    ok = out.write_image(zeros)
    for spec in specs[1:]:
        ok = ok and out.open(str(path), spec, "AppendSubimage") and out.write_image(zeros)
    assert out.close() and ok, oiio.geterror()


def crafted_exr(path, width: int, height: int, tile: tuple[int, int],
                channels: str = "BGR", attributes: dict[str, str] | None = None) -> None:
    """A one-part tiled EXR written byte by byte (float channels, no compression): its data
    window `width` x `height` in one tile of `tile` pixels (at least the image), whose chunk
    is 16 zero bytes, which reading then finds short; `attributes` as string attributes."""
    def attribute(name: str, kind: str, value: bytes) -> bytes:
        return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value

    window = struct.pack("<4i", 0, 0, width - 1, height - 1)
    names = b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1)
                     for n in sorted(channels)) + b"\0"
    header = (attribute("channels", "chlist", names)
              + attribute("compression", "compression", b"\0")
              + attribute("dataWindow", "box2i", window)
              + attribute("displayWindow", "box2i", window)
              + attribute("lineOrder", "lineOrder", b"\0")
              + attribute("pixelAspectRatio", "float", struct.pack("<f", 1.0))
              + attribute("screenWindowCenter", "v2f", struct.pack("<2f", 0.0, 0.0))
              + attribute("screenWindowWidth", "float", struct.pack("<f", 1.0))
              + attribute("tiles", "tiledesc", struct.pack("<IIB", *tile, 0))
              + b"".join(attribute(k, "string", v.encode())
                         for k, v in (attributes or {}).items()))
    assert tile[0] >= width and tile[1] >= height, "one tile only"
    head = b"\x76\x2f\x31\x01" + struct.pack("<i", 2 | 0x200) + header + b"\0"
    chunk = struct.pack("<5i", 0, 0, 0, 0, 16) + bytes(16)  # tile (0, 0) level (0, 0)
    with open(path, "wb") as f:
        f.write(head + struct.pack("<Q", len(head) + 8) + chunk)
