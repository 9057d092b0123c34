"""Image metrics against a reference, one idea per module: pixel errors (`error`), FLIP
(`flip`, NVIDIA's evaluator), SSIM (`ssim`, scikit-image), temporal error over paths
(`temporal`). `score` computes any choice of them over several masks at once.

| name | what | better |
|---|---|---|
| psnr | peak signal-to-noise ratio of linear RGB, peak 1 (dB; inf if identical) | higher |
| rmse | root mean squared channel error (linear) | lower |
| max_error | largest per-pixel error (largest absolute channel difference) | lower |
| frac_off | fraction of pixels whose per-pixel error exceeds the threshold | lower |
| relmse | relative MSE: mean of (t - r)^2 / (r^2 + 0.01) (HDR-safe) | lower |
| p50, p95, p99 | percentiles of the per-pixel error | lower |
| flip | HDR-FLIP of the linear images (mean of the per-pixel map, 0..1) | lower |
| flip_ldr | LDR-FLIP of the sRGB previews (8-bit, as written by `--preview`) | lower |
| ssim | SSIM of the sRGB-encoded images (Gaussian 11x11 window, sigma 1.5) | higher |

FLIP and SSIM need the `metrics` extra (flip-evaluator, scikit-image); without it they are
NaN and `score` says so once in `missing`.
"""

from __future__ import annotations

import math

import numpy as np

from . import flip as _flip
from . import ssim as _ssim
from .error import ERROR_NAMES, error_metrics

METRICS = (*ERROR_NAMES, "flip", "flip_ldr", "ssim")
DEFAULT_METRICS = METRICS
HIGHER_IS_BETTER = {"psnr", "ssim"}


def preview(linear: np.ndarray) -> np.ndarray:
    """The sRGB preview of a linear image as `--preview` writes it (8-bit), as floats 0..1."""
    from ..output.png import linear_to_srgb

    return np.floor(linear_to_srgb(linear) * 255.0 + 0.5) / 255.0


def parse_metrics(spec: str | None) -> tuple[str, ...]:
    """'psnr,flip' -> ('psnr', 'flip'); None or 'all' -> every metric. ValueError names
    unknown ones."""
    if spec is None or spec.strip() == "all":
        return METRICS
    names = tuple(n.strip() for n in spec.split(",") if n.strip())
    unknown = [n for n in names if n not in METRICS]
    if unknown or not names:
        raise ValueError(f"unknown metric(s) {', '.join(unknown) or '(none)'}; "
                         f"choose from {', '.join(METRICS)}")
    return names


def score(test: np.ndarray, reference: np.ndarray, masks: dict[str, np.ndarray | None],
          *, threshold: float = 0.1, metrics: tuple[str, ...] = DEFAULT_METRICS,
          encoded: bool = False, maps: dict | None = None) -> dict[str, dict[str, float]]:
    """{scope: {metric: value}} for each named mask (None = whole image).

    `encoded`: both images are sRGB-encoded already (PNGs): LDR-FLIP and SSIM use them as
    they are and HDR-FLIP is NaN. `maps`, if given, receives the per-pixel maps computed
    ('flip', 'flip_ldr', 'ssim'). FLIP and SSIM are NaN without their libraries."""
    out: dict[str, dict[str, float]] = {scope: {} for scope in masks}
    wanted_errors = [m for m in metrics if m in ERROR_NAMES]
    if wanted_errors:
        for scope, mask in masks.items():
            values = error_metrics(test, reference, mask, threshold)
            out[scope].update({m: values[m] for m in wanted_errors})
    computed: dict[str, np.ndarray | None] = {}
    if "flip" in metrics:
        computed["flip"] = (None if encoded or not _flip.available()
                            else _flip.flip_map(reference, test, "hdr"))
    if "flip_ldr" in metrics:
        if _flip.available():
            ldr = (reference, test) if encoded else (preview(reference), preview(test))
            computed["flip_ldr"] = _flip.flip_map(*ldr, "ldr")
        else:
            computed["flip_ldr"] = None
    if "ssim" in metrics:
        small = min(np.shape(test)[:2]) < 2 * _ssim.PAD + 1
        computed["ssim"] = (None if small or not ssim_available()
                            else _ssim.ssim_map(reference, test, encoded=encoded))
    for name, value_map in computed.items():
        mean = _ssim.mean_over if name == "ssim" else _flip.mean_over
        for scope, mask in masks.items():
            out[scope][name] = math.nan if value_map is None else mean(value_map, mask)
        if maps is not None and value_map is not None:
            maps[name] = value_map
    return {scope: {m: values[m] for m in metrics} for scope, values in out.items()}


def ssim_available() -> bool:
    try:
        import skimage.metrics  # noqa: F401
    except ImportError:
        return False
    return True


def missing_libraries(metrics: tuple[str, ...]) -> list[str]:
    """Packages the chosen metrics need that are not installed."""
    missing = []
    if {"flip", "flip_ldr"} & set(metrics) and not _flip.available():
        missing.append("flip-evaluator")
    if "ssim" in metrics and not ssim_available():
        missing.append("scikit-image")
    return missing
