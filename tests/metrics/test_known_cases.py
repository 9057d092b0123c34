"""Every metric on cases whose answer is known: identical images, a checkerboard moved by
one pixel (expected values computed here from the definitions, not by the libraries), and
a mask covering the whole image."""

from __future__ import annotations

import math

import numpy as np
import pytest

from reflectcli.metrics import METRICS, parse_metrics, score
from reflectcli.metrics.error import RELMSE_EPSILON, error_metrics
from reflectcli.metrics.flip import flip_map
from reflectcli.metrics.ssim import PAD
from reflectcli.metrics.temporal import temporal_errors

SQUARE = 8


def checkerboard(h=48, w=64, square=SQUARE):
    y, x = np.mgrid[0:h, 0:w]
    board = (((y // square) + (x // square)) % 2).astype(np.float32)
    return np.repeat(board[:, :, None], 3, axis=2)


def shifted(board):
    return np.roll(board, 1, axis=1)  # one pixel right, wrapping (the board is periodic)


def test_identical_images():
    img = np.random.default_rng(1).random((40, 50, 3)).astype(np.float32)
    m = score(img, img.copy(), {"image": None})["image"]
    assert m["psnr"] == math.inf and m["rmse"] == 0 and m["relmse"] == 0
    assert m["p50"] == m["p95"] == m["p99"] == 0
    assert m["flip"] == 0 and m["flip_ldr"] == 0
    assert m["ssim"] == pytest.approx(1.0, abs=1e-12)


def test_shifted_checkerboard_pixel_errors():
    """Shifting an s-pixel checkerboard by one pixel flips one column in s: MSE = 1/s."""
    ref = checkerboard()
    test = shifted(ref)
    m = error_metrics(test, ref)
    assert m["psnr"] == pytest.approx(10 * math.log10(SQUARE))
    assert m["rmse"] == pytest.approx(math.sqrt(1 / SQUARE))
    assert m["frac_off"] == pytest.approx(1 / SQUARE)
    # of the flipped pixels half are black in the reference, half white
    expected_relmse = (1 / SQUARE) * 0.5 * (1 / RELMSE_EPSILON + 1 / (1 + RELMSE_EPSILON))
    assert m["relmse"] == pytest.approx(expected_relmse)
    assert (m["p50"], m["p95"], m["p99"]) == (0.0, 1.0, 1.0)  # 12.5% of pixels are off by 1


def _naive_ssim(x, y):
    """Wang et al.'s SSIM, written out: Gaussian window (sigma 1.5, radius 5) applied with
    an explicit kernel over a mirrored border, population statistics, mean of the interior."""
    r = PAD
    t = np.arange(-r, r + 1)
    g = np.exp(-(t**2) / (2 * 1.5**2))
    g /= g.sum()
    kernel = np.outer(g, g)

    def blur(img):
        p = np.pad(img, r, mode="symmetric")
        out = np.zeros_like(img)
        for dy in range(2 * r + 1):
            for dx in range(2 * r + 1):
                out += kernel[dy, dx] * p[dy:dy + img.shape[0], dx:dx + img.shape[1]]
        return out

    c1, c2 = 0.01**2, 0.03**2
    values = []
    for ch in range(3):
        a, b = x[:, :, ch].astype(np.float64), y[:, :, ch].astype(np.float64)
        ma, mb = blur(a), blur(b)
        va, vb, cov = blur(a * a) - ma**2, blur(b * b) - mb**2, blur(a * b) - ma * mb
        s = ((2 * ma * mb + c1) * (2 * cov + c2)) / ((ma**2 + mb**2 + c1) * (va + vb + c2))
        values.append(s[r:-r, r:-r].mean())
    return float(np.mean(values))


def test_shifted_checkerboard_ssim():
    ref = checkerboard()
    test = shifted(ref)  # 0 and 1 are their own sRGB encodings: the board is unchanged
    m = score(test, ref, {"image": None}, metrics=("ssim",))["image"]
    assert m["ssim"] == pytest.approx(_naive_ssim(test, ref), abs=1e-9)
    assert 0.5 < m["ssim"] < 0.95


def test_shifted_checkerboard_flip():
    """FLIP has no closed form here; what is known: the error sits on the moved edges (none
    in the middle of squares far from them), a shift left or right and a vertical shift of
    the transposed board give the same figure, and it is well inside (0, 1)."""
    ref = checkerboard(64, 64, 16)
    right = shifted(ref)
    left = np.roll(ref, -1, axis=1)
    down = np.roll(ref, 1, axis=0)
    for mode in ("ldr", "hdr"):
        fmap = flip_map(ref, right, mode)
        edges = np.abs(right - ref).max(axis=-1) > 0
        assert fmap[edges].mean() > 3 * fmap[~edges].mean() > 0
        assert fmap[8::16, 8::16].max() < 1e-6  # square centers, 8 pixels from any edge
        mean = float(fmap.mean())
        assert 0.01 < mean < 0.5
        assert float(flip_map(ref, left, mode).mean()) == pytest.approx(mean, rel=1e-3)
        assert float(flip_map(ref, down, mode).mean()) == pytest.approx(mean, rel=1e-3)


def test_whole_image_mask_gives_full_image_figures():
    rng = np.random.default_rng(2)
    ref = rng.random((30, 40, 3)).astype(np.float32) * 2
    test = np.clip(ref + 0.1 * rng.standard_normal(ref.shape), 0, None).astype(np.float32)
    full = score(test, ref, {"all": np.ones((30, 40), bool), "image": None})
    assert full["all"] == full["image"]
    from skimage.metrics import structural_similarity

    from reflectcli.metrics.ssim import srgb
    expected = structural_similarity(srgb(ref), srgb(test), data_range=1.0, channel_axis=-1,
                                     gaussian_weights=True, sigma=1.5,
                                     use_sample_covariance=False)
    assert full["image"]["ssim"] == pytest.approx(expected, abs=1e-12)


def test_mask_restricts():
    ref = np.zeros((20, 20, 3), np.float32)
    test = ref.copy()
    test[:10] = 0.5
    m = score(test, ref, {"top": np.arange(20)[:, None].repeat(20, 1) < 10,
                          "bottom": np.arange(20)[:, None].repeat(20, 1) >= 10,
                          "none": np.zeros((20, 20), bool)}, metrics=("psnr", "flip"))
    assert m["bottom"]["psnr"] == math.inf and m["top"]["psnr"] == pytest.approx(
        -20 * math.log10(0.5))
    assert m["top"]["flip"] > m["bottom"]["flip"]
    assert math.isnan(m["none"]["psnr"]) and math.isnan(m["none"]["flip"])


def test_flip_refuses_bad_input_instead_of_exiting():
    good = np.zeros((8, 8, 3), np.float32)
    for bad, mode in ((good[:, :, :2], "hdr"), (good[:4], "hdr"), (good - 1, "hdr"),
                      (good + np.nan, "hdr"), (good + 2, "ldr")):
        with pytest.raises(ValueError):
            flip_map(good, bad, mode)
    with pytest.raises(ValueError):
        flip_map(good, good, "HDRish")
    # an all-black reference (no exposure range) is scored, not an exit
    assert float(flip_map(good, good + 0.5, "hdr").mean()) > 0


def test_parse_metrics():
    assert parse_metrics(None) == METRICS == parse_metrics("all")
    assert parse_metrics("psnr, flip") == ("psnr", "flip")
    with pytest.raises(ValueError, match="nope"):
        parse_metrics("psnr,nope")


def test_temporal_error_known_cases():
    rng = np.random.default_rng(3)
    ref = [rng.random((6, 7, 3)) for _ in range(5)]
    # the same motion as the reference, with a constant error: no temporal error
    per, total = temporal_errors([r + 0.3 for r in ref], ref)
    assert per == pytest.approx([0.0] * 4) and total == pytest.approx(0.0)
    # flicker: +d on odd frames, so every change is off by d
    d = 0.25
    per, total = temporal_errors([r + d * (t % 2) for t, r in enumerate(ref)], ref)
    assert per == pytest.approx([d] * 4) and total == pytest.approx(d)
    # a static reference, a technique lagging... one frame behind a still reference is exact
    still = [ref[0]] * 5
    per, total = temporal_errors(still, still)
    assert total == 0
    # lag: the technique shows the previous reference frame
    lagged = [ref[0]] + ref[:-1]
    per, _ = temporal_errors(lagged, ref)
    for t in range(1, 5):
        prev = ref[t - 2] if t >= 2 else ref[0]
        expected = (ref[t - 1] - prev) - (ref[t] - ref[t - 1])
        assert per[t - 1] == pytest.approx(math.sqrt(np.mean(expected**2)))
    # masks: a frame whose mask is empty gives NaN, and is left out of the total
    masks = [None, np.zeros((6, 7), bool)] + [np.ones((6, 7), bool)] * 3
    per, total = temporal_errors([r + d * (t % 2) for t, r in enumerate(ref)], ref, masks)
    assert math.isnan(per[0]) and per[1:] == pytest.approx([d] * 3) and total == pytest.approx(d)
    assert temporal_errors(ref[:1], ref[:1]) == ([], pytest.approx(math.nan, nan_ok=True))
