"""Two image files scored against each other (what `reflect compare` prints).

EXRs are linear; PNGs (and any other 8-bit format) are taken as sRGB-encoded. Comparing an
encoded file with a linear one, or frames of different scenes or frame indices (the EXR
attributes `reflect:scene`, `reflect:frame`), is allowed but warned about: the figures
would not mean what they seem to.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from ..errors import Problem, Problems
from . import DEFAULT_METRICS, missing_libraries, score

LINEAR_EXTENSIONS = (".exr", ".hdr")


@dataclass
class Comparison:
    scopes: dict[str, dict[str, float]]   # scope description -> metric -> value
    warnings: list[str] = field(default_factory=list)


def input_problem(path: str) -> str | None:
    """Why `path` is no image `compare` may read, or None: only a regular file within the
    size limit (a named pipe blocked OpenImageIO's open for good, deaf to SIGTERM), and a
    header within the render's image limits, its tiles too (a 7 MB tiled EXR claiming
    60000 x 60000 pixels was a MemoryError traceback: output/exr.size_problem)."""
    import OpenImageIO as oiio

    from ..config.files import file_problem
    from ..config.limits import (
        MAX_IMAGE_CHANNELS,
        MAX_IMAGE_FILE_BYTES,
        MAX_IMAGE_PIXELS,
        MAX_IMAGE_SIDE,
    )
    from ..output.exr import size_problem

    reason = file_problem(path, MAX_IMAGE_FILE_BYTES, "image file")
    if reason is not None:
        return reason
    inp = oiio.ImageInput.open(path)
    if inp is None:
        return f"cannot read {path}: {oiio.geterror()}"
    try:
        spec = inp.spec()
    finally:
        inp.close()
    return size_problem(spec, MAX_IMAGE_SIDE, MAX_IMAGE_PIXELS, MAX_IMAGE_CHANNELS)


def _read(path: str, mask_channel: str | None) -> tuple[dict, dict]:
    from ..c_stderr import c_stderr
    from ..output.exr import read_exr

    said: list[str] = []  # libpng's own "libpng error: ..." line: OpenImageIO's error says it
    with c_stderr(said):
        reason = input_problem(path)
    if reason is not None:
        raise Problems([Problem(path, "", reason.splitlines()[0])])
    try:
        with c_stderr(said):
            channels, attrs = read_exr(path)
    except OSError as e:
        raise Problems([Problem(path, "", str(e).splitlines()[0])]) from None
    missing = [c for c in ("R", "G", "B") if c not in channels]
    if mask_channel and mask_channel not in channels:
        missing.append(mask_channel)
    if missing:
        raise Problems([Problem(path, "channels", f"missing {', '.join(missing)}")])
    return channels, attrs


def compare_files(first: str, second: str, *, metrics: tuple[str, ...] = DEFAULT_METRICS,
                  mask_channel: str | None = None, threshold: float = 0.1) -> Comparison:
    """Score `second` against `first` (the reference) over the whole image and, with
    `mask_channel`, over the pixels where that channel is > 0 in both."""
    (ca, attrs_a), (cb, attrs_b) = (_read(p, mask_channel) for p in (first, second))
    a, b = (np.stack([c[k] for k in "RGB"], axis=-1) for c in (ca, cb))
    if a.shape != b.shape:
        raise Problems([Problem(second, "", f"size {b.shape[1]}x{b.shape[0]} differs from "
                                f"{a.shape[1]}x{a.shape[0]}")])
    warnings = []
    linear = [os.path.splitext(p)[1].lower() in LINEAR_EXTENSIONS for p in (first, second)]
    if linear[0] != linear[1]:
        png, exr = (first, second) if linear[1] else (second, first)
        warnings.append(f"{png} is sRGB-encoded and {exr} linear: the figures compare unlike "
                        "encodings (compare two EXRs, or two previews)")
    for key, what in (("reflect:scene", "scenes"), ("reflect:frame", "frames")):
        va, vb = attrs_a.get(key), attrs_b.get(key)
        if va is not None and vb is not None and str(va) != str(vb):
            warnings.append(f"{what} differ: {key} is '{va}' in {first} and '{vb}' in {second}")
    missing = missing_libraries(metrics)
    if missing:
        warnings.append(f"FLIP/SSIM need {' and '.join(missing)} (the metrics extra: "
                        "pip install 'reflect[metrics]'); shown as nan")
    h, w = a.shape[:2]
    masks: dict[str, np.ndarray | None] = {f"all {h * w} pixels": None}
    if mask_channel:
        mask = (ca[mask_channel] > 0) & (cb[mask_channel] > 0)
        masks[f"{int(mask.sum())} pixels where {mask_channel} > 0"] = mask
    try:
        scopes = score(b, a, masks, threshold=threshold, metrics=metrics,
                       encoded=not any(linear))
    except ValueError as e:  # e.g. negative or non-finite values refused by FLIP
        raise Problems([Problem(second, "", str(e))]) from None
    return Comparison(scopes, warnings)


def format_value(name: str, value: float, threshold: float) -> str:
    if isinstance(value, float) and math.isnan(value):
        return "nan"
    if name == "psnr":
        return f"{value:.4f} dB"
    if name == "frac_off":
        return f"{value:.6g} (> {threshold})"
    if name in ("ssim", "flip", "flip_ldr"):
        return f"{value:.6f}"
    return f"{value:.6g}"
