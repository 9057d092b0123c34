"""The warp's splat kernels against slow, obviously correct references of their visibility
rules, and their independence of the thread count."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import projection_of
from naive import splat_spread, splat_zbuffer

from reflectcli.maps.warp import (
    SAME_SURFACE,
    WarpBuffers,
    raster_runs,
    splat,
    splat_pixels,
    spread,
)


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


def _pixels(sx, sy, z, mh, mw, shape, stencil, radius, box=None, bands=None):
    """The one-pixel splat (radius 0: over the stencil) and, for radius > 0, its spread;
    each reached pixel's payload row must be its zexel's (checked here for every caller)."""
    h, w = shape
    x0, x1, y0, y1 = box or (0, w, 0, h)
    region = (max(x0 - radius, 0), min(x1 + radius, w), max(y0 - radius, 0),
              min(y1 + radius, h))
    buffers = WarpBuffers(h, w)
    proj = projection_of(sx, sy, z, mh, mw, shape)
    payload = np.random.default_rng(3).random((sx.size, 3)).astype(np.float32)
    out = np.full((h, w, 3), -5.0, np.float32)
    splat_pixels(proj, raster_runs(mh, mw), mw, 0, stencil,
                 buffers.best_zd, buffers.best_id, False,
                 region, True, radius == 0, bands, payload, out)
    if radius == 0:
        got_z, got_id = buffers.best_zd[..., 0], buffers.best_id
    else:
        stride = 1 << (sx.size - 1).bit_length()
        spread(buffers.best_zd, buffers.best_id, radius, stencil, (x0, x1, y0, y1),
               buffers.out_z, buffers.out_id, [payload], stride, out, bands)
        got_z, got_id = buffers.out_z, buffers.out_id
    reached = got_id >= 0
    np.testing.assert_array_equal(out[reached], payload[got_id[reached]])
    return got_z, got_id


@pytest.mark.parametrize("seed", range(4))
def test_pixel_splat_matches_the_reference(seed):
    sx, sy, z, mh, mw, shape = _zexels(seed)
    stencil = np.random.default_rng(seed + 10).random(shape) < 0.8
    _, got = _pixels(sx, sy, z, mh, mw, shape, stencil, 0)
    np.testing.assert_array_equal(got, splat_zbuffer(sx, sy, z, np.zeros(sx.size), mw,
                                                     stencil))


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("radius", [1, 2, 3])
@pytest.mark.parametrize("sub_box", [False, True])
def test_spread_matches_the_reference(seed, radius, sub_box):
    """Wide fixed splats: the one-pixel splat spread over squares, with holes (sparse
    zexels), two surfaces, zexels at infinity, and a stencil box inside the screen (zexels
    beyond the box's reach are culled by the projection: here by hand, for both)."""
    rng = np.random.default_rng(seed + 20)
    sx, sy, z, mh, mw, shape = _zexels(seed, mh=12, mw=14)
    z[rng.random(z.size) < 0.05] = np.inf
    stencil = rng.random(shape) < 0.8
    box = None
    if sub_box:
        box = (3, 16, 2, 13)
        x0, x1, y0, y1 = box
        inside = np.zeros(shape, bool)
        inside[y0:y1, x0:x1] = True
        stencil &= inside
        with np.errstate(invalid="ignore"):
            far = ((sx < x0 - radius) | (sx >= x1 + radius) | (sy < y0 - radius)
                   | (sy >= y1 + radius))
        sx = np.where(far, np.nan, sx).astype(np.float32)
    got_z, got_id = _pixels(sx, sy, z, mh, mw, shape, stencil, radius, box)
    want_z, want_id = splat_spread(sx, sy, z, radius, stencil)
    np.testing.assert_array_equal(got_id, want_id)
    np.testing.assert_array_equal(got_z, want_z)
    assert (got_id >= 0).sum() > (want_id >= 0).size // 4


@pytest.mark.parametrize("bands", [2, 3, 7])
@pytest.mark.parametrize("radius", [0, 1, 2])
def test_pixel_splat_does_not_depend_on_the_band_split(bands, radius):
    """The one-pixel splat's bands and the spread's (rows run with a ring of keys)."""
    sx, sy, z, mh, mw, shape = _zexels(7)
    stencil = np.ones(shape, bool)
    one = _pixels(sx, sy, z, mh, mw, shape, stencil, radius, bands=1)[1].copy()
    np.testing.assert_array_equal(one, _pixels(sx, sy, z, mh, mw, shape, stencil, radius,
                                               bands=bands)[1])


@pytest.mark.parametrize("threads", [1, 2])
def test_pixel_splat_matches_at_thread_counts_with_a_partly_full_stencil(threads):
    """Bands of about equal landings run on either thread, and a band whose stencil rows are
    all set skips the stencil test: neither changes the result (a stencil full in its top
    half, sparse in its bottom half, so some bands test and some do not)."""
    import numba

    sx, sy, z, mh, mw, shape = _zexels(11)
    stencil = np.random.default_rng(12).random(shape) < 0.7
    stencil[: shape[0] // 2] = True
    want = splat_zbuffer(sx, sy, z, np.zeros(sx.size), mw, stencil)
    before = numba.get_num_threads()
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    try:
        for bands in (1, 4, 9):
            got = _pixels(sx, sy, z, mh, mw, shape, stencil, 0, bands=bands)[1]
            np.testing.assert_array_equal(got, want)
    finally:
        numba.set_num_threads(before)


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


def test_gather_and_fill_blend_match_twins():
    """dprm's colour gather (any number of maps, four per pass) and its fill-and-blend, with
    and without a previous frame, against numpy twins on random buffers."""
    from naive import fill_and_blend, gather_rows

    from reflectcli.maps.warp import fill_blend, gather_colors

    rng = np.random.default_rng(5)
    h, w = 24, 32
    for stride, n_maps in ((50, 1), (50, 3), (50, 6), (64, 1), (64, 5)):
        per_map = [rng.random((stride, 3)).astype(np.float32) for _ in range(n_maps)]
        best_id = rng.integers(-1, n_maps * stride, size=(h, w)).astype(np.int64)
        best_id[rng.random((h, w)) < 0.3] = -1
        out = rng.random((h, w, 3)).astype(np.float32)
        box = (3, 29, 2, 20)
        want = gather_rows(best_id, stride, per_map, box, out)
        gather_colors(best_id, stride, per_map, box, out)
        np.testing.assert_array_equal(out, want)
    stencil = rng.random((h, w)) < 0.7
    background = np.array([0.1, 0.2, 0.3], np.float32)
    reflectance = np.array([0.9, 0.8, 0.7], np.float32)
    # (strided: reflected as the first three channels of colour-and-triangle rows, as dprm's
    # surface reconstruction has them; the frame's rgb is (H, W, 3))
    for has_prev, temporal, strided in ((False, True, False), (True, True, False),
                                        (False, False, False), (False, False, True)):
        reflected = rng.random((h, w, 3)).astype(np.float32)
        prev_rgb = rng.random((h, w, 3)).astype(np.float32)
        prev_filled = rng.random((h, w)) < 0.5
        rgb = rng.random((h, w, 3)).astype(np.float32)
        want = fill_and_blend(stencil, best_id, reflected, prev_rgb if has_prev else None,
                              prev_filled, background, reflectance, rgb)
        holes = np.zeros((h, w), np.float32)
        save_rgb = np.zeros((h, w, 3), np.float32)
        save_filled = np.zeros((h, w), bool)
        got_reflected = reflected.copy()
        if strided:
            got_reflected = np.zeros((h, w, 4), np.float32)[:, :, :3]
            got_reflected[...] = reflected
        fill_blend(stencil, best_id, got_reflected, has_prev, prev_rgb, prev_filled, temporal,
                   save_rgb, save_filled, background, reflectance, rgb, holes)
        np.testing.assert_allclose(rgb, want[0], rtol=1e-6, atol=1e-7)
        np.testing.assert_array_equal(holes, want[1])
        # the reflected colours of stencil pixels; the others stay as they were
        np.testing.assert_array_equal(got_reflected[stencil], want[2][stencil])
        np.testing.assert_array_equal(got_reflected[~stencil], reflected[~stencil])
        if temporal:
            np.testing.assert_array_equal(save_filled, want[3])
            np.testing.assert_array_equal(save_rgb[want[3]], want[2][want[3]])


@pytest.mark.parametrize("maps", [2, 6])
@pytest.mark.parametrize("radius", [0, 1])
@pytest.mark.parametrize("width", [4, 3, 5])
def test_payload_rows_follow_the_ids_over_several_maps(radius, width, maps):
    """Several maps into one buffer (ids slot * stride + index, stride a power of two): every
    reached pixel's payload row is the row of its id's map and zexel (rows of the widths
    the splat copies with a constant width, 3 and 4, and of another; more maps than a
    spread copies itself, MAPS_AT_ONCE, get theirs from the gather)."""
    shape = (16, 20)
    h, w = shape
    buffers = WarpBuffers(h, w)
    stencil = np.random.default_rng(1).random(shape) < 0.8
    region = (0, w, 0, h)
    out = np.full((h, w, width), -5.0, np.float32)
    stride = 1 << (24 * 24 - 1).bit_length()
    payloads = []
    for slot in range(maps):
        sx, sy, z, mh, mw, _ = _zexels(slot + 30)
        payloads.append(np.random.default_rng(slot).random((sx.size, width)).astype(np.float32))
        splat_pixels(projection_of(sx, sy, z, mh, mw, shape), raster_runs(mh, mw), mw,
                     slot * stride, stencil, buffers.best_zd,
                     buffers.best_id, False, region, slot == 0, radius == 0, None,
                     payloads[slot], out)
    ids = buffers.best_id
    if radius:
        spread(buffers.best_zd, buffers.best_id, radius, stencil, region, buffers.out_z,
               buffers.out_id, payloads, stride, out)
        ids = buffers.out_id
    reached = ids >= 0
    slots = ids[reached] // stride
    assert set(slots) == set(range(maps))
    want = np.array([payloads[s][k] for s, k in zip(slots, ids[reached] % stride,
                                                      strict=True)])
    np.testing.assert_array_equal(out[reached], want)
