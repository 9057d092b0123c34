"""FLIP (NVIDIA's image-difference evaluator, PyPI `flip-evaluator`): LDR-FLIP on sRGB
previews, HDR-FLIP on linear images; per-pixel maps in [0, 1], 0 where identical.

`flip_evaluator.evaluate` ends the process (`sys.exit`) on bad arguments and lets its C++
core fail on bad arrays, so every input is checked here first and refused with ValueError.
HDR-FLIP picks its exposure range from the reference (start from its peak luminance, stop
from its median); an all-black reference has no range, so it gets exposures 0..0 as FLIP's
own Python tool does. Viewing conditions are FLIP's default, 67 pixels per degree.
"""

from __future__ import annotations

import math

import numpy as np

MODES = ("ldr", "hdr")
PIXELS_PER_DEGREE = 67.0


def available() -> bool:
    try:
        import flip_evaluator  # noqa: F401
    except ImportError:
        return False
    return True


def _validate(reference: np.ndarray, test: np.ndarray, mode: str) -> tuple[np.ndarray, ...]:
    if mode not in MODES:
        raise ValueError(f"FLIP mode must be one of {MODES}, got {mode!r}")
    arrays = []
    for name, img in (("reference", reference), ("test", test)):
        img = np.asarray(img)
        if img.ndim != 3 or img.shape[2] != 3:
            raise ValueError(f"FLIP: {name} must be (H, W, 3), got {img.shape}")
        if img.shape[0] < 1 or img.shape[1] < 1:
            raise ValueError(f"FLIP: {name} is empty")
        img = np.ascontiguousarray(img, np.float32)
        if not np.isfinite(img).all():
            raise ValueError(f"FLIP: {name} has non-finite values")
        if img.min() < 0:
            raise ValueError(f"FLIP: {name} has negative values")
        if mode == "ldr" and img.max() > 1:
            raise ValueError(f"FLIP: {name} has values above 1 (LDR expects [0, 1])")
        arrays.append(img)
    if arrays[0].shape != arrays[1].shape:
        raise ValueError(f"FLIP: image sizes differ: {arrays[0].shape} and {arrays[1].shape}")
    return tuple(arrays)


def flip_map(reference: np.ndarray, test: np.ndarray, mode: str = "hdr") -> np.ndarray:
    """(H, W) FLIP error map. `ldr`: sRGB-encoded inputs in [0, 1]; `hdr`: linear, >= 0."""
    import flip_evaluator

    ref, tst = _validate(reference, test, mode)
    parameters: dict = {"ppd": PIXELS_PER_DEGREE}
    if mode == "hdr":
        luminance = ref @ np.array([0.2126, 0.7152, 0.0722], np.float32)
        if float(luminance.max()) <= 0.0:
            parameters.update(startExposure=0.0, stopExposure=0.0)
    error, _, _ = flip_evaluator.evaluate(ref, tst, mode.upper(), inputsRGB=(mode == "ldr"),
                                          applyMagma=False, computeMeanError=False,
                                          parameters=parameters)
    return np.asarray(error, np.float32).reshape(ref.shape[:2])


def mean_over(error_map: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Mean of a per-pixel map over `mask` (all pixels if None); NaN if the mask is empty."""
    if mask is None:
        return float(np.mean(error_map, dtype=np.float64))
    if not mask.any():
        return math.nan
    return float(np.mean(error_map[mask], dtype=np.float64))
