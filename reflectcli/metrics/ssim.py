"""SSIM (Wang et al. 2004) through scikit-image, on display-encoded images.

SSIM was defined on gamma-encoded intensities, so linear frames are sRGB-encoded and
clipped to [0, 1] first (what the previews show) and `data_range` is 1. The window is the
paper's: Gaussian weights of sigma 1.5 (11 x 11), population covariances
(`use_sample_covariance=False`), K1 = 0.01, K2 = 0.03, each channel apart and the channels
averaged. The SSIM map is undefined within 5 pixels of the border (the window leaves the
image); scikit-image leaves those pixels out of its mean and so does `mean_over`, so a mask
covering the whole image gives exactly scikit-image's mean SSIM.
"""

from __future__ import annotations

import math

import numpy as np

SIGMA = 1.5
# scikit-image's Gaussian window: radius int(3.5 * sigma + 0.5) = 5, 11 x 11
PAD = int(3.5 * SIGMA + 0.5)


def srgb(linear: np.ndarray) -> np.ndarray:
    from ..output.png import linear_to_srgb

    return linear_to_srgb(linear).astype(np.float64)


def ssim_map(reference: np.ndarray, test: np.ndarray, encoded: bool = False) -> np.ndarray:
    """(H, W) SSIM map (channel mean). `encoded`: inputs are sRGB already, else linear.
    ValueError if the sizes differ or a side is shorter than the 11-pixel window."""
    from skimage.metrics import structural_similarity

    ref = np.asarray(reference, np.float64)
    tst = np.asarray(test, np.float64)
    if ref.shape != tst.shape:
        raise ValueError(f"SSIM: image sizes differ: {ref.shape} and {tst.shape}")
    if min(ref.shape[:2]) < 2 * PAD + 1:
        raise ValueError(f"SSIM: images under {2 * PAD + 1} pixels a side")
    if not encoded:
        ref, tst = srgb(ref), srgb(tst)
    _, full = structural_similarity(ref, tst, data_range=1.0, channel_axis=-1,
                                    gaussian_weights=True, sigma=SIGMA,
                                    use_sample_covariance=False, full=True)
    return full.mean(axis=-1)


def mean_over(ssim: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Mean SSIM over `mask` (all pixels if None), border pixels left out; NaN if empty."""
    inner = np.zeros(ssim.shape, bool)
    inner[PAD:-PAD, PAD:-PAD] = True
    if mask is not None:
        inner &= mask
    if not inner.any():
        return math.nan
    return float(np.mean(ssim[inner], dtype=np.float64))
