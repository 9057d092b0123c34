"""Image error metrics against a reference (linear RGB, peak 1): the bench's basic four.
The full set (relMSE, percentiles, FLIP, SSIM, temporal error) is in `reflectcli.metrics`."""

from __future__ import annotations

from ..metrics.error import error_metrics

METRIC_NAMES = ("psnr", "rmse", "max_error", "frac_off")


def image_metrics(a, b, mask=None, threshold: float = 0.1) -> dict[str, float]:
    """PSNR (dB, peak 1; inf if identical), RMSE, max abs error, and the fraction of pixels
    whose largest channel error exceeds `threshold`, over `mask` (all pixels if None).
    NaN if the mask is empty."""
    values = error_metrics(a, b, mask, threshold)
    return {name: values[name] for name in METRIC_NAMES}
