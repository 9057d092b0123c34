"""Image textures through OpenImageIO, decoded to linear RGB float32."""

from __future__ import annotations

import numpy as np

from ..c_stderr import c_stderr


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    c = np.asarray(c, dtype=np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def load_texture(path: str, srgb: bool) -> np.ndarray:
    """(H, W, 3) linear float32, row 0 at the top of the image (v = 1 maps to row 0)."""
    import OpenImageIO as oiio

    from ..config.files import file_problem
    from ..config.limits import (
        MAX_NUMBER,
        MAX_TEXTURE_BYTES,
        MAX_TEXTURE_CHANNELS,
        MAX_TEXTURE_SIDE,
        MAX_TEXTURE_TEXELS,
        MAX_TEXTURE_VALUES,
    )
    from ..output.exr import size_problem

    reason = file_problem(path, MAX_TEXTURE_BYTES, "texture file")
    if reason is not None:
        raise ValueError(reason)
    said: list[str] = []
    with c_stderr(said):
        inp = oiio.ImageInput.open(path)
    if inp is None:
        raise ValueError(f"cannot read image: {oiio.geterror() or '; '.join(said) or path}")
    try:
        spec = inp.spec()
        # the header's claims bound what the read allocates: side, texels, channels, values
        # and tiles (a 1 MB TIFF of 1024 x 1024 texels in 1000 channels, or a 385-byte EXR of
        # 16 x 16 texels in one tile of 20000 x 20000, was a MemoryError traceback). Only the
        # first part (subimage) and MIP level are read.
        problem = size_problem(spec, MAX_TEXTURE_SIDE, MAX_TEXTURE_TEXELS,
                               MAX_TEXTURE_CHANNELS, MAX_TEXTURE_VALUES)
        if problem is not None:
            raise ValueError(f"texture has {problem}".replace("pixels", "texels"))
        if spec.width * spec.height == 0:
            raise ValueError("texture has no pixels")
        # only the channels used: gray (1 or 2 channels: gray, alpha) or R, G, B
        used = 1 if spec.nchannels <= 2 else 3
        with c_stderr(said):
            pixels = inp.read_image(0, 0, 0, used, oiio.FLOAT)
    finally:
        inp.close()
    if pixels is None:
        why = "; ".join(said) or oiio.geterror()
        raise ValueError(f"cannot read image pixels: {path}" + (f" ({why})" if why else ""))
    pixels = np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, used)
    rgb = np.repeat(pixels, 3, axis=2) if used == 1 else pixels
    if not np.isfinite(rgb).all():
        raise ValueError("texture has non-finite texels (NaN or infinity)")
    linear = srgb_to_linear(rgb) if srgb else np.ascontiguousarray(rgb)
    if np.abs(linear).max() > MAX_NUMBER:  # as a color's limit: lit, it overflowed to NaN
        raise ValueError(f"texture has texels past +-{MAX_NUMBER:g} (linear)")
    return linear
