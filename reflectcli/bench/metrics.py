"""Image error metrics against a reference (linear RGB, peak 1)."""

from __future__ import annotations

import math

import numpy as np

METRIC_NAMES = ("psnr", "rmse", "max_error", "frac_off")


def image_metrics(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None,
                  threshold: float = 0.1) -> dict[str, float]:
    """PSNR (dB, peak 1; inf if identical), RMSE, max abs error, and the fraction of pixels
    whose largest channel error exceeds `threshold`, over `mask` (all pixels if None).
    Non-finite values (e.g. a +inf depth) are not expected in colors; NaN if mask is empty."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    if a.shape != b.shape:
        raise ValueError(f"image sizes differ: {a.shape} and {b.shape}")
    if mask is None:
        mask = np.ones(a.shape[:2], bool)
    if not mask.any():
        return {name: math.nan for name in METRIC_NAMES}
    diff = (a - b)[mask]
    mse = float(np.mean(diff**2))
    per_pixel = np.abs(diff).max(axis=-1) if diff.ndim > 1 else np.abs(diff)
    return {
        "psnr": math.inf if mse == 0 else 10.0 * math.log10(1.0 / mse),
        "rmse": math.sqrt(mse),
        "max_error": float(per_pixel.max()),
        "frac_off": float(np.mean(per_pixel > threshold)),
    }
