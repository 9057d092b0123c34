"""sRGB-encoded, clipped 8-bit PNG previews."""

from __future__ import annotations

import numpy as np

from .atomic import atomic_path
from .exr import write_image_at


def linear_to_srgb(c: np.ndarray) -> np.ndarray:
    c = np.clip(np.asarray(c, np.float32), 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)


def write_png(path: str, rgb: np.ndarray) -> None:
    with atomic_path(path) as tmp:
        write_png_at(tmp, path, rgb)


def write_png_at(tmp: str, path: str, rgb: np.ndarray) -> None:
    """write_png into `tmp`, an atomic_path of `path` that the caller renames (as
    exr.write_exr_at)."""
    import OpenImageIO as oiio

    data = np.ascontiguousarray((linear_to_srgb(rgb) * 255.0 + 0.5).astype(np.uint8))
    h, w = data.shape[:2]
    write_image_at(tmp, path, oiio.ImageSpec(w, h, 3, oiio.UINT8), data)
