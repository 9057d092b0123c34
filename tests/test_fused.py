"""reflectcli.fused: a * b + c rounded once."""

from __future__ import annotations

import numpy as np
from naive import fused_multiply_add
from numba import njit

from reflectcli.fused import fma


@njit(cache=True)
def _fma_all(a, b, c, out):
    for i in range(a.shape[0]):
        out[i] = fma(a[i], b[i], c[i])


def test_fma_rounds_once():
    """The exact a * b + c, rounded once (not the product's rounding, then the sum's), over
    random and cancelling operands."""
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(2, 2000))
    c = np.concatenate([rng.normal(size=1000), -(a[1000:] * b[1000:])])  # cancelling
    out = np.empty(2000)
    _fma_all(a, b, c, out)
    exact = np.array([fused_multiply_add(x, y, z) for x, y, z in zip(a, b, c, strict=True)])
    assert out.tobytes() == exact.tobytes()
    assert (out != a * b + c).any()  # the two roundings differ somewhere
