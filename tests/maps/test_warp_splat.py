"""The warp's splat kernel against a slow, obviously correct reference of its visibility rule,
and its independence of the thread count."""

from __future__ import annotations

import numpy as np
import pytest
from naive import splat_zbuffer

from reflectcli.maps.warp import SAME_SURFACE, raster_runs, splat


def _zexels(seed, mh=24, mw=24, width=20, height=16):
    rng = np.random.default_rng(seed)
    n = mh * mw
    sx = rng.uniform(-1, width + 1, n).astype(np.float32)
    sy = rng.uniform(-1, height + 1, n).astype(np.float32)
    # two surfaces, each with a little depth spread inside SAME_SURFACE, so both rules act
    z = np.where(rng.random(n) < 0.5, 2.0, 5.0) * (1 + rng.uniform(0, 0.5 * SAME_SURFACE, n))
    sx[rng.random(n) < 0.05] = np.nan
    inside = ~np.isnan(sx)
    sy = np.where(inside, np.clip(sy, 0, height - 1e-3), sy).astype(np.float32)
    sx = np.where(inside, np.clip(sx, 0, width - 1e-3), sx).astype(np.float32)
    return sx, sy, z.astype(np.float32), mh, mw, (height, width)


def _kernel(sx, sy, z, radii, mh, mw, shape, stencil, bands=None):
    best_zd = np.full((*shape, 2), np.inf, np.float32)
    best_id = np.full(shape, -1, np.int64)
    rows = np.floor(sy).reshape(mh, mw)
    with np.errstate(invalid="ignore"):
        row_lo = np.where(np.isnan(rows), 1 << 40, rows).min(axis=1).astype(np.int64)
        row_hi = np.where(np.isnan(rows), -1, rows).max(axis=1).astype(np.int64)
    splat(sx, sy, z, radii, raster_runs(mh, mw), mw, row_lo, row_hi, 0, sx.size, stencil,
          best_zd, best_id, False, bands)
    return best_id


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("radius", [0, 1, 2])
def test_splat_matches_the_reference(seed, radius):
    sx, sy, z, mh, mw, shape = _zexels(seed)
    stencil = np.random.default_rng(seed + 10).random(shape) < 0.8
    radii = np.full(sx.size, radius, np.int8)
    np.testing.assert_array_equal(_kernel(sx, sy, z, radii, mh, mw, shape, stencil),
                                  splat_zbuffer(sx, sy, z, radii, mw, stencil))


@pytest.mark.parametrize("bands", [2, 3, 7])
def test_splat_does_not_depend_on_the_band_split(bands):
    """Threads take bands of screen rows; the result must not depend on how many."""
    sx, sy, z, mh, mw, shape = _zexels(7)
    stencil = np.ones(shape, bool)
    radii = np.full(sx.size, 1, np.int8)
    one = _kernel(sx, sy, z, radii, mh, mw, shape, stencil, bands=1)
    np.testing.assert_array_equal(one, _kernel(sx, sy, z, radii, mh, mw, shape, stencil,
                                               bands=bands))


def test_projection_drops_nan_and_non_positive_depths():
    from reflectcli.maps.warp import project_map

    depth = np.array([[2.0, np.nan, 0.0, -1.0, np.inf]], np.float32)
    w = np.eye(4)
    w[0, 0] = 0.1
    w[3] = [0.0, 0.0, 1.0, 0.0]  # clip w = 1 for every (u, v, 1, delta): z = depth
    sx, _, z, _, _ = project_map(depth, w, 64, 64, 0.01)
    assert np.isfinite(sx[0]) and z[0] == 2.0
    assert np.isfinite(sx[4]) and z[4] == np.inf  # a direction (empty zexel) still warps
    assert np.isnan(sx[1:4]).all()
