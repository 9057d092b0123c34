"""Metrics on images whose errors are known exactly."""

from __future__ import annotations

import math

import numpy as np
import pytest

from reflectcli.bench.metrics import image_metrics


def test_identical_images():
    a = np.random.default_rng(0).random((8, 9, 3)).astype(np.float32)
    m = image_metrics(a, a.copy())
    assert m["psnr"] == math.inf and m["rmse"] == 0 and m["max_error"] == 0
    assert m["frac_off"] == 0


@pytest.mark.parametrize("offset", [0.5, 0.1, 0.01])
def test_known_offset(offset):
    a = np.zeros((4, 5, 3))
    b = a + offset
    m = image_metrics(a, b, threshold=0.05)
    assert m["rmse"] == pytest.approx(offset)
    assert m["psnr"] == pytest.approx(-20 * math.log10(offset))
    assert m["max_error"] == pytest.approx(offset)
    assert m["frac_off"] == (1.0 if offset > 0.05 else 0.0)


def test_mask_and_fraction():
    a = np.zeros((2, 2, 3))
    b = a.copy()
    b[0, 0] = [1.0, 0, 0]  # one pixel off by 1 in one channel
    assert image_metrics(a, b)["frac_off"] == 0.25
    assert image_metrics(a, b)["rmse"] == pytest.approx(math.sqrt(1 / 12))
    mask = np.array([[False, True], [True, True]])
    assert image_metrics(a, b, mask)["psnr"] == math.inf
    assert math.isnan(image_metrics(a, b, np.zeros((2, 2), bool))["psnr"])
    with pytest.raises(ValueError):
        image_metrics(a, np.zeros((3, 2, 3)))
