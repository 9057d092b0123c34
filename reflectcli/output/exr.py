"""EXR frames through OpenImageIO: float channels R, G, B, A, Z plus lowercase extras.

Metadata goes into string attributes; OIIO's DateTime is pinned so that identical renders
give byte-identical files (timings live in the log, never in the image).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .atomic import atomic_path
from .failures import image_failure

FIXED_DATETIME = "2000:01:01 00:00:00"


def pack_channels(channels: dict[str, np.ndarray]) -> tuple[list[str], np.ndarray]:
    """(names, (H, W, C) float32 array): a fresh copy of the channels, ready to write."""
    names = list(channels)
    data = np.ascontiguousarray(np.stack([channels[n] for n in names], axis=-1), np.float32)
    return names, data


def write_exr(path: str, channels: dict[str, np.ndarray], attributes: dict[str, str]) -> None:
    """Write (H, W) float channels in the given order, zip-compressed, atomically."""
    write_exr_packed(path, *pack_channels(channels), attributes)


def write_exr_packed(path: str, names: list[str], data: np.ndarray,
                     attributes: dict[str, str]) -> None:
    """write_exr of channels already packed by pack_channels."""
    with atomic_path(path) as tmp:
        write_exr_at(tmp, path, names, data, attributes)


def write_exr_at(tmp: str, path: str, names: list[str], data: np.ndarray,
                 attributes: dict[str, str]) -> None:
    """write_exr_packed into `tmp`, an atomic_path of `path` that the caller renames (a frame
    renames its files once its log row is written: frame_writer.py). A failure raises
    WriteFailed naming `path`, its reason found while `tmp` still fills the disk."""
    import OpenImageIO as oiio

    h, w = data.shape[:2]
    spec = oiio.ImageSpec(w, h, len(names), oiio.FLOAT)
    spec.channelnames = tuple(names)
    spec.attribute("compression", "zip")
    for key, value in attributes.items():
        spec.attribute(key, str(value))
    spec.attribute("DateTime", FIXED_DATETIME)
    write_image_at(tmp, path, spec, data)


def write_image_at(tmp: str, path: str, spec, data: np.ndarray) -> None:
    """`data` as the image `spec` describes into `tmp` (OpenImageIO picks the format by its
    extension); a failure is a WriteFailed naming `path`, its reason found while `tmp` still
    fills the disk."""
    import OpenImageIO as oiio

    out = oiio.ImageOutput.create(tmp)
    if out is None or not out.open(tmp, spec):
        raise image_failure(path, oiio.geterror())
    ok = out.write_image(data)
    ok = out.close() and ok
    if not ok:
        raise image_failure(path, oiio.geterror())
    if not _whole(tmp, spec):
        raise image_failure(path, "the file is shorter than what was written")


PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"


def _whole(tmp: str, spec) -> bool:
    """Whether `tmp` holds all OpenImageIO wrote: the disk filling up during the last flush
    at close lost the file's tail with every call reporting success (an EXR of 18,372 bytes
    kept as 16,384 and logged as a finished frame). An EXR's last scanline must read (one
    chunk decoded); a PNG must end with its IEND chunk."""
    import OpenImageIO as oiio

    if tmp.lower().endswith(".png"):
        with open(tmp, "rb") as f:
            f.seek(0, 2)
            if f.tell() < len(PNG_END):
                return False
            f.seek(-len(PNG_END), 2)
            return f.read() == PNG_END
    inp = oiio.ImageInput.open(tmp)
    if inp is None:
        oiio.geterror()
        return False
    try:
        last = inp.read_scanline(spec.y + spec.height - 1, 0, oiio.FLOAT)
        if last is None:
            inp.geterror()
        return last is not None
    finally:
        inp.close()


def read_exr_attributes(path: str) -> dict[str, str] | None:
    """The string attributes of an EXR's header, its pixels not read (None: unreadable)."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(path)
    if inp is None:
        oiio.geterror()  # read, so that it does not linger into a later error
        return None
    try:
        return _attributes(inp.spec())
    finally:
        inp.close()


def _attributes(spec) -> dict[str, str]:
    return {a.name: a.value for a in spec.extra_attribs}


def read_exr(path: str) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """(channels by name as (H, W) float32, string attributes). OIIO may reorder channels."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise OSError(f"cannot read {path}: {oiio.geterror()}")
    try:
        spec = inp.spec()
        data = inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)
        if data is None:  # a truncated or damaged file: a header, but not its pixels
            raise OSError(f"cannot read {path}: {inp.geterror() or oiio.geterror()}")
    finally:
        inp.close()
    data = np.asarray(data, np.float32).reshape(spec.height, spec.width, spec.nchannels)
    channels = {name: data[:, :, spec.channelindex(name)] for name in spec.channelnames}
    return channels, _attributes(spec)


def write_exr_parts(
    path: str, parts: list[tuple[str, dict[str, np.ndarray]]], attributes: dict[str, str],
    part_attributes: list[dict[str, str]] | None = None,
) -> None:
    """A multi-part EXR, one named part per entry (e.g. cube faces), written atomically.

    EXR cannot append a part later: open with every part's spec, then each further part in
    "AppendSubimage" mode (STACK-NOTES.md). All parts share the display window."""
    import OpenImageIO as oiio

    specs, datas = [], []
    for index, (name, channels) in enumerate(parts):
        names = list(channels)
        data = np.ascontiguousarray(np.stack([channels[n] for n in names], axis=-1), np.float32)
        h, w = data.shape[:2]
        spec = oiio.ImageSpec(w, h, len(names), oiio.FLOAT)
        spec.channelnames = tuple(names)
        spec.attribute("compression", "zip")
        spec.attribute("oiio:subimagename", name)
        own = part_attributes[index] if part_attributes else {}
        for key, value in {**attributes, **own}.items():
            spec.attribute(key, str(value))
        spec.attribute("DateTime", FIXED_DATETIME)
        specs.append(spec)
        datas.append(data)
    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(tmp)
        if out is None or not out.open(tmp, specs):
            raise image_failure(path, oiio.geterror())
        ok = out.write_image(datas[0])
        for spec, data in zip(specs[1:], datas[1:], strict=True):
            ok = ok and out.open(tmp, spec, "AppendSubimage") and out.write_image(data)
        ok = out.close() and ok
        if not ok:
            raise image_failure(path, oiio.geterror())


def size_problem(spec, side: int, pixels: int, channels: int) -> str | None:
    """Why an image header claims more than `side` pixels a side, `pixels` pixels or
    `channels` channels, in the image or in one tile, or None. The header alone: checked
    before any pixel is read, a file's claims bound what reading it allocates (a 7 MB tiled
    EXR claiming 60000 x 60000 pixels was a MemoryError in `compare`; a 385-byte one claiming
    64 x 64 pixels in tiles of 20000 x 20000 another)."""
    if (max(spec.width, spec.height) > side or spec.width * spec.height > pixels
            or spec.nchannels > channels):
        return (f"{spec.width}x{spec.height} pixels of {spec.nchannels} channels; the limit is "
                f"{side} a side, {pixels} pixels, {channels} channels")
    if max(spec.tile_width, spec.tile_height) > side or spec.tile_width * spec.tile_height > pixels:
        return (f"tiles of {spec.tile_width}x{spec.tile_height} pixels; the limit is {side} a "
                f"side, {pixels} pixels")
    return None


def read_exr_parts(
    path: str, fits: Callable[[int, object], str | None] | None = None,
) -> list[tuple[str, dict[str, np.ndarray], dict[str, str]]]:
    """Every part of an EXR: (name, channels by name, attributes). Raises OSError if unreadable.

    `fits(index, spec)` sees each part's header before any pixel of any part is read and says
    why the file is refused (raised as an OSError `part <index>: <why>`), or None: what a
    caller expects bounds what the read allocates. Reads each part with the explicit
    subimage argument (after seek_subimage, the short read_image forms silently return
    part 0)."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise OSError(f"cannot read {path}: {oiio.geterror()}")
    parts = []
    try:
        index = 0
        while fits is not None and inp.seek_subimage(index, 0):
            problem = fits(index, inp.spec())
            if problem is not None:
                raise OSError(f"part {index}: {problem}")
            index += 1
        index = 0
        while inp.seek_subimage(index, 0):
            spec = inp.spec()
            data = inp.read_image(index, 0, 0, spec.nchannels, oiio.FLOAT)
            if data is None:
                raise OSError(f"cannot read {path} part {index}: {inp.geterror()}")
            data = np.asarray(data, np.float32).reshape(spec.height, spec.width, spec.nchannels)
            channels = {n: data[:, :, spec.channelindex(n)] for n in spec.channelnames}
            attrs = {a.name: a.value for a in spec.extra_attribs}
            parts.append((str(spec.getattribute("oiio:subimagename") or index), channels, attrs))
            index += 1
    finally:
        inp.close()
    return parts
