"""Pixel-error metrics against a reference: PSNR, RMSE, max error, fraction of pixels off,
relative MSE and percentiles of the per-pixel error, over a mask or the whole image.

Images are linear RGB (H, W, 3), peak 1 for PSNR. The per-pixel error is the largest
absolute channel difference (what `frac_off`, `max_error` and the percentiles use).
Relative MSE divides each squared channel error by the reference's squared value plus
`RELMSE_EPSILON` (Rousselle et al.'s denoising measure), so bright HDR pixels do not drown
dark ones and black reference pixels do not divide by zero.
"""

from __future__ import annotations

import math

import numpy as np

ERROR_NAMES = ("psnr", "rmse", "max_error", "frac_off", "relmse", "p50", "p95", "p99")
RELMSE_EPSILON = 1e-2


def _check(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    if a.shape != b.shape:
        raise ValueError(f"image sizes differ: {a.shape} and {b.shape}")
    return a, b


def per_pixel_error(test: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """(H, W) largest absolute channel difference."""
    a, b = _check(test, reference)
    diff = np.abs(a - b)
    return diff.max(axis=-1) if diff.ndim > 2 else diff


def error_metrics(test: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None,
                  threshold: float = 0.1) -> dict[str, float]:
    """Every ERROR_NAMES figure over `mask` (all pixels if None); NaN for an empty mask.

    PSNR is in dB with peak 1 (inf if identical); percentiles are of the per-pixel error."""
    a, b = _check(test, reference)
    if mask is None:
        mask = np.ones(a.shape[:2], bool)
    if not mask.any():
        return {name: math.nan for name in ERROR_NAMES}
    diff = (a - b)[mask]
    mse = float(np.mean(diff**2))
    per_pixel = np.abs(diff).max(axis=-1) if diff.ndim > 1 else np.abs(diff)
    p50, p95, p99 = (float(v) for v in np.percentile(per_pixel, [50, 95, 99]))
    return {
        "psnr": math.inf if mse == 0 else 10.0 * math.log10(1.0 / mse),
        "rmse": math.sqrt(mse),
        "max_error": float(per_pixel.max()),
        "frac_off": float(np.mean(per_pixel > threshold)),
        "relmse": float(np.mean(diff**2 / (b[mask] ** 2 + RELMSE_EPSILON))),
        "p50": p50, "p95": p95, "p99": p99,
    }
