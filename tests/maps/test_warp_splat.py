"""The warp's splat kernel against a slow, obviously correct reference of its visibility rule,
and its independence of the thread count."""

from __future__ import annotations

import numba
import numpy as np
import pytest

from reflectcli.maps.warp import SAME_SURFACE, raster_runs, splat


def _reference(sx, sy, z, radii, mw, stencil):
    """Zexels in index order; per pixel: a zexel clearly nearer than the front so far takes
    it; one on the front surface takes it if it lands nearer the pixel center (ties to the
    lower index)."""
    h, w = stencil.shape
    front = np.full((h, w), np.inf)
    best = np.full((h, w), -1)
    dist = np.full((h, w), np.inf)
    for k in range(sx.size):
        if np.isnan(sx[k]):
            continue
        px, py, r = int(np.floor(sx[k])), int(np.floor(sy[k])), int(radii[k])
        for y in range(py - r, py + r + 1):
            for x in range(px - r, px + r + 1):
                if not (0 <= y < h and 0 <= x < w and stencil[y, x]):
                    continue
                d = (np.float32(sx[k]) - x - 0.5) ** 2 + (np.float32(sy[k]) - y - 0.5) ** 2
                if best[y, x] < 0 or z[k] < front[y, x] * (1 - SAME_SURFACE):
                    best[y, x], dist[y, x], front[y, x] = k, d, z[k]
                elif z[k] <= front[y, x] * (1 + SAME_SURFACE):
                    if d < dist[y, x] or (d == dist[y, x] and k < best[y, x]):
                        best[y, x], dist[y, x] = k, d
                    front[y, x] = min(front[y, x], z[k])
    return best


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


def _kernel(sx, sy, z, radii, mh, mw, shape, stencil):
    best_zd = np.full((*shape, 2), np.inf, np.float32)
    best_id = np.full(shape, -1, np.int64)
    rows = np.floor(sy).reshape(mh, mw)
    with np.errstate(invalid="ignore"):
        row_lo = np.where(np.isnan(rows), 1 << 40, rows).min(axis=1).astype(np.int64)
        row_hi = np.where(np.isnan(rows), -1, rows).max(axis=1).astype(np.int64)
    splat(sx, sy, z, radii, raster_runs(mh, mw), mw, row_lo, row_hi, 0, sx.size, stencil,
          best_zd, best_id, False)
    return best_id


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("radius", [0, 1, 2])
def test_splat_matches_the_reference(seed, radius):
    sx, sy, z, mh, mw, shape = _zexels(seed)
    stencil = np.random.default_rng(seed + 10).random(shape) < 0.8
    radii = np.full(sx.size, radius, np.int8)
    np.testing.assert_array_equal(_kernel(sx, sy, z, radii, mh, mw, shape, stencil),
                                  _reference(sx, sy, z, radii, mw, stencil))


def test_splat_does_not_depend_on_the_thread_count():
    sx, sy, z, mh, mw, shape = _zexels(7)
    stencil = np.ones(shape, bool)
    radii = np.full(sx.size, 1, np.int8)
    results = []
    for threads in (1, numba.config.NUMBA_NUM_THREADS):
        numba.set_num_threads(threads)
        results.append(_kernel(sx, sy, z, radii, mh, mw, shape, stencil))
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    np.testing.assert_array_equal(results[0], results[1])
