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


MAX_FRAME_CHANNELS = 16  # a frame reflect writes: R G B A Z mirror and at most 5 of its own

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
    chunk decoded), in every part when `spec` is a list of the parts' specs (a multi-part
    map: its parts' chunks follow one another, the file's tail is the last part's); a PNG
    must end with its IEND chunk."""
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
        for index, part in enumerate(spec if isinstance(spec, list) else [spec]):
            if not inp.seek_subimage(index, 0):
                inp.geterror()
                return False
            last = inp.read_scanline(part.y + part.height - 1, 0, oiio.FLOAT)
            if last is None:
                inp.geterror()
                return False
        return True
    finally:
        inp.close()


def read_exr_header(path: str):
    """An image's header (OpenImageIO's ImageSpec of its first part), its pixels not read
    (None: unreadable)."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(path)
    if inp is None:
        oiio.geterror()  # read, so that it does not linger into a later error
        return None
    try:
        return inp.spec()
    finally:
        inp.close()


def header_attributes(spec) -> dict[str, str]:
    """A header's attributes by name (the string ones reflect writes, and the others)."""
    return {a.name: a.value for a in spec.extra_attribs}


def read_exr(path: str, fits: Callable[[object], str | None] | None = None,
             ) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """(channels by name as (H, W) float32, string attributes). OIIO may reorder channels.
    Raises OSError if unreadable.

    `fits(spec)` sees the header before any pixel is read and says why the file is refused
    (raised as an OSError `<path>: <why>`), or None: what the caller expects bounds what the
    read allocates (size_problem, frame_problem)."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise OSError(f"cannot read {path}: {oiio.geterror()}")
    try:
        spec = inp.spec()
        problem = fits(spec) if fits is not None else None
        if problem is not None:
            raise OSError(f"{path}: {problem}")
        data = inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)
        if data is None:  # a truncated or damaged file: a header, but not its pixels
            raise OSError(f"cannot read {path}: "
                          f"{inp.geterror() or oiio.geterror() or 'pixels unreadable'}")
    finally:
        inp.close()
    data = np.asarray(data, np.float32).reshape(spec.height, spec.width, spec.nchannels)
    channels = {name: data[:, :, spec.channelindex(name)] for name in spec.channelnames}
    return channels, header_attributes(spec)


def write_exr_parts(
    path: str, parts: list[tuple[str, dict[str, np.ndarray]]], attributes: dict[str, str],
    part_attributes: list[dict[str, str]] | None = None,
) -> None:
    """A multi-part EXR, one named part per entry (e.g. cube faces), written atomically and,
    as a frame is, checked whole before it is renamed into place (_whole: every part's last
    scanline reads); a failure is a WriteFailed naming `path`.

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
        if not _whole(tmp, specs):  # a full disk at the last flush: see _whole
            raise image_failure(path, "the file is shorter than what was written")


def size_problem(spec, side: int, pixels: int, channels: int,
                 values: int | None = None) -> str | None:
    """Why an image header claims more than `side` pixels a side, `pixels` pixels or
    `channels` channels, in the image or in one tile, more than `values` values (pixels
    times channels) in the image or in one tile, or deep data, or None. The header alone
    (any OpenImageIO ImageSpec): checked before any pixel is read, a file's claims bound
    what reading it allocates (a 7 MB tiled EXR claiming 60000 x 60000 pixels was a
    MemoryError in `compare`; a 385-byte one claiming 64 x 64 pixels in tiles of
    20000 x 20000 another; a 1 MB TIFF of 1024 x 1024 pixels in 1000 channels a third, as
    a texture)."""
    if spec.deep:
        return "deep data (per-pixel samples), which reflect does not read"
    if (max(spec.width, spec.height) > side or spec.width * spec.height > pixels
            or spec.nchannels > channels):
        return (f"{spec.width}x{spec.height} pixels of {spec.nchannels} channels; the limit is "
                f"{side} a side, {pixels} pixels, {channels} channels")
    if values is not None and spec.width * spec.height * spec.nchannels > values:
        return (f"{spec.width}x{spec.height} pixels of {spec.nchannels} channels, "
                f"{spec.width * spec.height * spec.nchannels} values; the limit is {values} "
                f"values (pixels times channels)")
    if max(spec.tile_width, spec.tile_height) > side or spec.tile_width * spec.tile_height > pixels:
        return (f"tiles of {spec.tile_width}x{spec.tile_height} pixels; the limit is {side} a "
                f"side, {pixels} pixels")
    if values is not None and spec.tile_width * spec.tile_height * spec.nchannels > values:
        return (f"tiles of {spec.tile_width}x{spec.tile_height} pixels of {spec.nchannels} "
                f"channels; the limit is {values} values (pixels times channels)")
    return None


def frame_problem(spec, width: int, height: int) -> str | None:
    """Why a header is not that of a frame `width` x `height` reflect wrote, or None:
    that size, R, G and B among at most MAX_FRAME_CHANNELS channels, tiles (if any) within
    the frame, no deep data. A frame's own pixels are then all a read of it allocates
    (--resume --preview reads a kept frame; a planted one claiming 60000 x 60000 pixels
    was read whole)."""

    problem = size_problem(spec, max(width, height), width * height, MAX_FRAME_CHANNELS)
    if problem is not None:
        return problem
    if (spec.width, spec.height) != (width, height):
        return f"{spec.width}x{spec.height} pixels where the frame is {width}x{height}"
    missing = [c for c in "RGB" if c not in spec.channelnames]
    if missing:
        return f"no channel {', '.join(missing)}"
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
