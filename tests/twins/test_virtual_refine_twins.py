"""The screen refinement (reflector grid, bilinear samples, Gauss-Newton walks) and its
tile culling against their slow twins."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import compiled_only
from naive import (
    grid_sample,
    grid_sample_slope,
    part_candidates,
    refine_point,
    refine_walk,
    reflector_grid,
    rows_of,
    scan,
    tile_bounds,
)
from naive import joined as naive_joined
from numba import njit

from reflectcli.camera import Camera
from reflectcli.virtual import refine, tiles
from reflectcli.virtual.tiles import PartTiles, joined


def sphere_grid(w=40, h=32):
    """A reflector-only item buffer of a unit sphere, by ray casting: (camera, triangle ids
    (one 'triangle' per pixel, its corners all at the hit), Q, R, inside)."""
    cam = Camera(np.array([0.3, 0.4, 3.5]), np.zeros(3), np.array([0.0, 1.0, 0.0]), 45.0, w, h,
                 0.1, 50.0)
    d = cam.pixel_directions(1)[:, :, 0]
    d = d / np.linalg.norm(d, axis=2, keepdims=True)
    o = cam.eye
    b = d @ o
    disc = b * b - (o @ o - 1.0)
    inside = disc > 0
    t = -b - np.sqrt(np.where(inside, disc, 0.0))
    q = o + t[..., None] * d
    n = q.copy()
    r = d - 2 * np.einsum("ijk,ijk->ij", d, n)[..., None] * n
    return cam, inside, np.where(inside[..., None], q, np.nan), np.where(inside[..., None], r,
                                                                         np.nan)


@compiled_only
def test_reflector_grid_matches_twin():
    rng = np.random.default_rng(0)
    h, w = 7, 9
    corners = rng.normal(size=(5, 3, 3))
    normals = rng.normal(size=(5, 3, 3))
    tri = rng.integers(-1, 5, (h, w)).astype(np.int32)
    b = rng.dirichlet([1, 1, 1], (h, w)).astype(np.float32)
    eye = np.array([0.0, 0.5, 4.0])
    got = refine.reflector_grid(tri, b[..., 1].copy(), b[..., 2].copy(), corners, normals, eye)
    want = reflector_grid(tri, b[..., 1], b[..., 2], corners, normals, eye)
    for g, x in zip(got, want, strict=True):
        np.testing.assert_array_equal(np.isnan(g), np.isnan(x))
        np.testing.assert_allclose(g[~np.isnan(x)], x[~np.isnan(x)], rtol=1e-12, atol=1e-12)
    # R alone, into kept arrays holding an earlier call's values
    r_only = np.zeros((h, w, 3))
    q_none, r = refine.reflector_grid(tri, b[..., 1].copy(), b[..., 2].copy(), corners,
                                      normals, eye, out=(None, r_only))
    assert q_none is None and r is r_only
    np.testing.assert_array_equal(r, got[1])


def test_grid_sample_matches_twin():
    rng = np.random.default_rng(1)
    _, inside, q, r = sphere_grid(16, 12)
    pts = list(rng.uniform(-1, 17, (300, 2))) + [(0.5, 0.5), (8.0, 6.0), (16.0, 12.0)]
    for sx, sy in pts:
        ok, *got = refine._sample_slope(inside.view(np.int8), 1, q, r, sx, sy)
        got = got[0:3] + got[9:12]  # Q and R
        want = grid_sample(inside, q, r, sx, sy)
        assert (ok > 0) == (want is not None), (sx, sy)
        if ok:
            np.testing.assert_allclose(got[:3], want[0], atol=1e-12)
            np.testing.assert_allclose(got[3:], want[1], atol=1e-12)


def test_grid_sample_slope_matches_twin():
    """Q, R and their screen derivatives against forward differences of the bilinear sample,
    in cells with all four corners inside the part and at its edge (corners missing)."""
    rng = np.random.default_rng(3)
    _, inside, q, r = sphere_grid(16, 12)
    pts = rng.uniform(-1, 17, (400, 2))
    pts = pts[(np.abs(pts - 0.5 - np.round(pts - 0.5)) > 1e-3).all(axis=1)]  # off cell edges
    edges = 0
    for sx, sy in pts:
        ok, *got = refine._sample_slope(inside.view(np.int8), 1, q, r, sx, sy)
        want = grid_sample_slope(inside, q, r, sx, sy)
        assert (ok > 0) == (want is not None), (sx, sy)
        if not ok:
            continue
        np.testing.assert_allclose(got[0:3], want[0], atol=1e-12)
        np.testing.assert_allclose(got[9:12], want[3], atol=1e-12)
        for g, x in ((got[3:6], want[1]), (got[6:9], want[2]), (got[12:15], want[4]),
                     (got[15:18], want[5])):
            np.testing.assert_allclose(g, x, atol=1e-5)
        x0, y0 = int(np.floor(sx - 0.5)), int(np.floor(sy - 0.5))
        cell = inside[max(y0, 0):y0 + 2, max(x0, 0):x0 + 2]
        edges += cell.size < 4 or not cell.all()
    assert edges > 10


def test_refinement_walks_match_twin():
    """Whole walks, EXACT or not, from seeds up to 6 pixels off, against the twin's plain
    Gauss-Newton (forward-difference Jacobian): the same status and end point."""
    rng = np.random.default_rng(4)
    cam, inside, q, r = sphere_grid()
    ys, xs = np.nonzero(inside)
    pick = rng.choice(len(ys), 80, replace=False)
    pts = q[ys[pick], xs[pick]] + r[ys[pick], xs[pick]] * rng.uniform(0.5, 3.0, (80, 1))
    pts[60:] = rng.normal(size=(20, 3)) * 2.0  # mostly reflected nowhere near
    seeds = np.stack([xs[pick], ys[pick]], 1) + rng.uniform(-6, 6, (80, 2))
    statuses = []
    for p, seed in zip(pts, seeds, strict=True):
        status, *end = refine._walk(p, inside.view(np.int8), 1, q, r, seed[0], seed[1], 20)
        want_status, want_end = refine_walk(p, seed, inside, q, r)
        assert status == want_status, (p, seed)
        statuses.append(status)
        if status != refine.NONE:
            np.testing.assert_allclose(end, want_end, atol=1e-5)
    assert statuses.count(refine.EXACT) > 30 and statuses.count(refine.BOUNDARY) > 10


def test_refinement_lanes_match_walks_one_at_a_time():
    """_refine runs walks side by side (lanes), retries included: each point's answer is
    the one its walks give one at a time (_walk from the seed, then from the retry where
    the first walk found nothing, or only the boundary of a part the tiles say it reaches),
    bit for bit, at 1 and 2 threads."""
    import numba

    rng = np.random.default_rng(11)
    cam, inside, q, r = sphere_grid()
    ys, xs = np.nonzero(inside)
    pick = rng.choice(len(ys), 300)
    pts = q[ys[pick], xs[pick]] + r[ys[pick], xs[pick]] * rng.uniform(0.5, 3.0, (300, 1))
    pts[200:] = rng.normal(size=(100, 3)) * 2.0
    seeds = np.stack([xs[pick], ys[pick]], 1) + rng.uniform(-8, 8, (300, 2))
    retry = np.stack([xs[pick[::-1]], ys[pick[::-1]]], 1) + 0.5
    seeds[::7] = np.nan
    retry[::5] = np.nan
    reach = rng.random(300) < 0.7
    owner = inside.view(np.int8)
    want = np.full((300, 3), np.nan)
    want_status = np.zeros(300, np.int8)
    for k, p in enumerate(pts):
        status, e = refine.NONE, None
        if np.isfinite(seeds[k]).all():
            status, *e = refine._walk(p, owner, 1, q, r, seeds[k, 0], seeds[k, 1], 20)
        if (status == refine.NONE or (status == refine.BOUNDARY and reach[k])) \
                and np.isfinite(retry[k, 0]):
            again, *f = refine._walk(p, owner, 1, q, r, retry[k, 0], retry[k, 1], 20)
            if again == refine.EXACT or (status == refine.NONE and again != refine.NONE):
                status, e = again, f
        if status == refine.NONE:
            continue
        v, d = np.array(e) - cam.eye, p - np.array(e)
        # summed in the kernel's order (numpy's `@` rounds as the CPU's BLAS kernel does)
        le = np.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2)
        lp = np.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
        want[k] = cam.eye + v / le * (le + lp)
        want_status[k] = status
    assert len(set(want_status.tolist())) == 3
    before = numba.get_num_threads()
    try:
        for threads in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
            numba.set_num_threads(threads)
            got, status = refine.refine_virtual(pts, seeds, inside, q, r, cam.eye, retry,
                                                reach=reach)
            np.testing.assert_array_equal(status, want_status)
            np.testing.assert_array_equal(got, want)
    finally:
        numba.set_num_threads(before)


def test_screen_refinement_matches_twin():
    """Points reflected at known pixel centers, searched from seeds a few pixels off: where
    the kernel reports EXACT it lands on the twin's least-squares solution."""
    rng = np.random.default_rng(2)
    cam, inside, q, r = sphere_grid()
    ys, xs = np.nonzero(inside)
    pick = rng.choice(len(ys), 40, replace=False)
    pts = q[ys[pick], xs[pick]] + r[ys[pick], xs[pick]] * rng.uniform(0.5, 3.0, (40, 1))
    seeds = np.stack([xs[pick], ys[pick]], 1) + 0.5 + rng.uniform(-3, 3, (40, 2))
    seeds[0] = np.nan  # no seed: NONE
    got, status = refine.refine_virtual(pts, seeds, inside, q, r, cam.eye)
    assert status[0] == refine.NONE and np.isnan(got[0]).all()
    exact = np.flatnonzero(status == refine.EXACT)
    assert len(exact) > 25
    for k in exact:
        want = refine_point(pts[k], seeds[k], inside, q, r, cam.eye)
        assert want is not None
        np.testing.assert_allclose(got[k], want, atol=1e-4)


def test_refinement_skips_only_retries_that_cannot_matter():
    """With the tiles' reach, a point no tile reaches walks once from its seed: the retry
    it skips could not have found an exact reflection. Same bytes as retrying everyone."""
    rng = np.random.default_rng(9)
    cam, inside, q, r = sphere_grid()
    patch = np.zeros_like(inside)  # a part: a patch of the sphere, so most points miss it
    ys, xs = np.nonzero(inside)
    y0, x0 = ys[len(ys) // 2] - 6, xs[len(xs) // 2] - 6
    patch[y0:y0 + 12, x0:x0 + 12] = inside[y0:y0 + 12, x0:x0 + 12]
    tiles = PartTiles(patch, q, r, size=4)
    py, px = np.nonzero(patch)
    pick = rng.choice(len(py), 60)
    near = q[py[pick], px[pick]] + r[py[pick], px[pick]] * rng.uniform(0.5, 3.0, (60, 1))
    pts = np.concatenate([near, rng.normal(size=(300, 3)) * 3.0])
    reach, retry = tiles.scan(pts, q, r)
    seeds = np.stack([px[rng.choice(len(px), len(pts))],
                      py[rng.choice(len(py), len(pts))]], 1) + 0.5
    seeds += rng.uniform(-6, 6, seeds.shape)
    got, status = refine.refine_virtual(pts, seeds, patch, q, r, cam.eye, retry, reach=reach)
    want, want_status = refine.refine_virtual(pts, seeds, patch, q, r, cam.eye, retry)
    assert got.tobytes() == want.tobytes() and status.tobytes() == want_status.tobytes()
    assert (~reach & (status == refine.BOUNDARY)).sum() > 50  # retries skipped
    assert not (~reach & (status == refine.EXACT)).any()
    assert (status == refine.EXACT).sum() > 20


@pytest.mark.parametrize("size", [4, 8, 12])
def test_tile_bounds_match_twin(size):
    _, inside, q, r = sphere_grid()
    inside = inside.copy()
    inside[5:9, 10:30] = False  # holes: tiles with few pixels, grown blocks straddling them
    tiles = PartTiles(inside, q, r, size=size)
    center, radius, axis, half, pixel = tile_bounds(inside, q, r, size)
    for got, want in ((tiles.center, center), (tiles.radius, radius), (tiles.axis, axis),
                      (tiles.half, half)):
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(tiles.pixel, pixel)


@njit(cache=True)
def _acos_each_and_of_least(cos):
    widest = -np.inf
    least = np.inf
    for c in cos:
        widest = max(widest, math.acos(c))
        least = min(least, c)
    return widest, math.acos(least)


@compiled_only
def test_widest_angle_is_the_acos_of_the_least_cosine():
    """_tile_bounds takes a tile's widest angle as acos of its least cosine, one acos a
    tile: the same bits as the widest of each pixel's acos, because the acos kernels call is
    decreasing (glibc's, not correctly rounded since 2.34, was found monotone over 1.4e8
    adjacent pairs): checked here over random cosines, cosines a few ulps apart, and the
    ends."""
    rng = np.random.default_rng(4)
    cases = [rng.uniform(-1.0, 1.0, 50) for _ in range(200)]
    for centre in (-1.0, -0.5, 0.0, 0.3, 1.0 - 1e-9, 1.0):
        near = np.nextafter(np.full(8, centre), rng.choice([-2.0, 2.0], 8))
        cases.append(np.clip(np.concatenate([[centre], near]), -1.0, 1.0))
    for cos in cases:
        each, once = _acos_each_and_of_least(cos)
        assert np.float64(each).tobytes() == np.float64(once).tobytes()


def test_tile_scan_with_a_wide_cone_matches_twin():
    """A tile whose cone is at least a right angle wide takes the arcsine branch."""
    rng = np.random.default_rng(8)
    _, inside, q, r = sphere_grid()
    tiles = PartTiles(inside, q, r, size=8)
    tiles.half[::3] = 1.7
    pts = rng.normal(size=(300, 3)) * 3.0
    reach, seeds = tiles.scan(pts, q, r)
    want_reach, want_seeds = scan(pts, tiles.center, tiles.radius, tiles.axis, tiles.half,
                                  tiles.pixel, tiles.margin, q, r)
    np.testing.assert_array_equal(reach, want_reach)
    np.testing.assert_array_equal(seeds, want_seeds)


def test_tile_scan_matches_twin():
    rng = np.random.default_rng(3)
    _, inside, q, r = sphere_grid()
    tiles = PartTiles(inside, q, r, size=8)
    pts = np.concatenate([rng.normal(size=(200, 3)) * 3.0, [tiles.center[0]]])
    reach, seeds = tiles.scan(pts, q, r)
    want_reach, want_seeds = scan(pts, tiles.center, tiles.radius, tiles.axis, tiles.half,
                                  tiles.pixel, tiles.margin, q, r)
    np.testing.assert_array_equal(reach, want_reach)
    np.testing.assert_array_equal(seeds, want_seeds)
    assert reach.any() and not reach.all()
    # a small patch of the sphere (a part whose rays leave in a narrow cone): its own ball and
    # cone hold every point a tile reaches, and the culled scan (with polygons) answers alike
    # wherever the part needs a seed
    ys, xs = np.nonzero(inside)
    patch = np.zeros_like(inside)
    y0, x0 = ys[len(ys) // 2], xs[len(xs) // 2]
    patch[y0:y0 + 12, x0:x0 + 12] = inside[y0:y0 + 12, x0:x0 + 12]
    small = PartTiles(patch, q, r, size=4)
    far = np.concatenate([pts, rng.normal(size=(600, 3)) * 20.0])
    polygons = rng.integers(0, len(far), (300, 3))
    full_reach, full_seeds = small.scan(far, q, r)
    assert full_reach.any()
    assert small.candidates(far)[full_reach].all()
    assert not small.candidates(far).all()  # the cull does cull
    culled_reach, culled_seeds = small.scan(far, q, r, polygons)
    np.testing.assert_array_equal(culled_reach, full_reach)
    todo = full_reach.copy()
    todo[polygons[full_reach[polygons].any(axis=1)].ravel()] = True
    np.testing.assert_array_equal(culled_seeds[todo], full_seeds[todo])


def test_tile_scan_blocks_skip_only_tiles_that_reach_none_of_them():
    """_scan_reached (blocks of points skip tiles by the block's ball) against _scan (every
    tile meets every point): the same reach, and the same seeds wherever a tile reaches, on
    tight clusters of points (blocks with small balls, so that tiles are skipped) scattered
    around the sphere, many of them at the edges of the tiles' cones; and _block_misses
    never skips a tile one of the ball's points passes (points sampled in the ball, up to
    its surface)."""
    rng = np.random.default_rng(5)
    _, inside, q, r = sphere_grid()
    part = PartTiles(inside, q, r, size=4)
    centres = rng.normal(size=(24, 3)) * 3.0
    pts = np.concatenate([c + rng.normal(size=(128, 3)) * 10.0 ** rng.uniform(-4, -1)
                          for c in centres])
    pts.flags.writeable = False  # as PartTiles.scan hands them (the kernels' one signature)
    rows = np.arange(len(pts))
    args = (part.center, part.radius, part.axis, part.half, part.pixel, part.margin, q, r)
    want_reach, want_seeds = np.zeros(len(pts), bool), np.full((len(pts), 2), np.nan)
    tiles._scan(pts, rows, *args[:6], q, r, want_reach, want_seeds)
    reach, seeds = np.zeros(len(pts), bool), np.full((len(pts), 2), np.nan)
    tiles._scan_reached(pts, rows, *args[:6], q, r, reach, seeds, 2)
    np.testing.assert_array_equal(reach, want_reach)
    np.testing.assert_array_equal(seeds[reach], want_seeds[reach])
    assert np.isnan(seeds[~reach]).all() and reach.any() and not reach.all()
    a = part.half + part.margin
    skipped = 0
    for c in centres:
        for rho in (1e-3, 0.05, 0.3):
            for j in range(len(part.center)):
                if a[j] >= 0.5 * np.pi or not tiles._block_misses(
                        c[0], c[1], c[2], rho, part.center[j], part.radius[j] * 1.001,
                        part.axis[j], np.cos(a[j]), np.sin(a[j])):
                    continue
                skipped += 1
                d = rng.normal(size=(64, 3))
                d *= rho * rng.uniform(0.0, 1.0, (64, 1)) ** 0.3 / np.linalg.norm(
                    d, axis=1, keepdims=True)
                # and the ball's point turned furthest toward the tile's axis (seen from
                # the tile's centre): the one the bound must still keep out
                out = (c - part.center[j]) / np.linalg.norm(c - part.center[j])
                toward = part.axis[j] - np.dot(part.axis[j], out) * out
                if np.linalg.norm(toward) > 0:
                    d = np.concatenate([d, [rho * toward / np.linalg.norm(toward)]])
                got, _ = scan(c + d, part.center[j:j + 1], part.radius[j:j + 1],
                              part.axis[j:j + 1], part.half[j:j + 1], part.pixel[j:j + 1],
                              part.margin, q, r)
                assert not got.any()
    assert skipped > 100


def test_rows_of_matches_twin():
    """tiles.rows_of (one kernel) against flatnonzero part by part: parts with no marked
    point, with every point marked, a part of exactly a block."""
    rng = np.random.default_rng(4)
    for n in (0, 1, 300, tiles._BLOCK):
        marks = rng.random((6, n)) < 0.3
        marks[1] = False
        marks[2] = True
        if n >= tiles._BLOCK:
            marks[3] = False
            marks[3, :tiles._BLOCK] = True
        got = tiles.rows_of(marks)
        want = rows_of(marks, tiles._BLOCK)
        for g, w in zip(got, want, strict=True):
            assert g.dtype == np.int64
            np.testing.assert_array_equal(g, w)


def test_part_candidates_and_join_match_twins():
    """The part's cull (ball and cone) and the polygon join, against their twins, on points
    near the cone's edge too."""
    rng = np.random.default_rng(11)
    _, inside, q, r = sphere_grid()
    tiles = PartTiles(inside, q, r, size=8)
    pts = np.concatenate([rng.normal(size=(400, 3)) * 3.0, [tiles.part_center],
                          tiles.part_center + rng.normal(size=(50, 3)) * 1e-3])
    half = tiles.part_half + tiles.margin
    want = part_candidates(pts, tiles.part_center, tiles.part_radius, tiles.part_axis, half)
    got = tiles.candidates(pts)
    # the kernel tests cosines, the twin angles: they may part only within 1e-9 of the edge
    v = pts - tiles.part_center
    dist = np.linalg.norm(v, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):  # the point at the center
        angle = np.arccos(np.clip(v @ tiles.part_axis / dist, -1, 1))
        spread = np.arcsin(np.minimum(tiles.part_radius / dist, 1.0))
    edge = np.abs(angle - half - spread) < 1e-7
    np.testing.assert_array_equal(got[~edge], want[~edge])
    assert got.any() and (~edge).sum() > 400
    flag = rng.random(len(pts)) < 0.05
    polygons = rng.integers(0, len(pts), (120, 3))
    np.testing.assert_array_equal(joined(flag, polygons), naive_joined(flag, polygons))


def _numpy_sums_as_balls_does() -> bool:
    """Whether this machine's numpy takes (N, 3) @ (3,) as fma(a2, u2, fma(a0, u0, a1 u1))
    (OpenBLAS on this machine kind) and its arccos is the C library's acos: the order and
    function tiles._balls reproduces; elsewhere it matches numpy to rounding only."""
    from reflectcli.fused import fma

    rng = np.random.default_rng(12)
    a, u = rng.normal(size=(64, 3)), rng.normal(size=3)
    want = [fma(float(x[2]), float(u[2]), fma(float(x[0]), float(u[0]), float(x[1] * u[1])))
            for x in a]
    c = rng.uniform(-1.0, 1.0, 256)
    return bool((a @ u == np.array(want)).all()
                and (np.arccos(c) == np.array([math.acos(v) for v in c])).all())


def test_part_balls_match_twin_bit_for_bit():
    """Each part's ball and cone over its tiles in one kernel (tiles._balls) are numpy's
    (PartTiles' code before session 17, the twin) bit for bit where numpy sums as the
    kernel does: parts of one tile, of many, with axes spread and gathered, with none, and
    with axes summing to zero."""
    from naive import part_ball

    from reflectcli.virtual.tiles import _parts_balls

    bits = _numpy_sums_as_balls_does()
    rng = np.random.default_rng(1)
    for trial in range(60):
        counts = rng.integers(0, 60, rng.integers(1, 8))
        counts[0] = max(counts[0], 1)
        if trial % 4 == 1:  # parts of a single tile (numpy's one-row product)
            counts[: 2] = 1
        n = int(counts.sum())
        center, radius = rng.normal(size=(n, 3)) * 3.0, rng.uniform(0.0, 1.0, n)
        axis = rng.normal(size=(n, 3))
        if trial % 3 == 0:  # gathered, as a part's tiles' axes are
            axis = axis * 0.1 + np.array([0.3, 0.8, -0.5])
        axis /= np.linalg.norm(axis, axis=1, keepdims=True)
        if trial == 5:  # two opposite axes: no cone axis
            counts, axis = np.array([2]), np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])
            n, center, radius = 2, center[:2], radius[:2]
        half = rng.uniform(0.0, 0.5, n)
        starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        got = _parts_balls(center, radius, axis, half, starts)
        for p in range(len(counts)):
            rows = slice(starts[p], starts[p + 1])
            want = part_ball(center[rows], radius[rows], axis[rows], half[rows])
            for g, w in zip(got[p], want, strict=True):
                g, w = np.asarray(g, np.float64), np.asarray(w, np.float64)
                if bits:
                    assert g.tobytes() == w.tobytes()
                else:
                    np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-12)


def test_tile_bounds_of_a_flat_mirror_clamp_the_cosine():
    """Every pixel reflecting the same direction (a flat mirror): the tiles' axes are that
    direction up to rounding, and a cosine rounding above 1 is clamped (the widest angle
    0, not NaN), as the twin's np.clip does."""
    h = w = 26
    inside = np.ones((h, w), bool)
    q = np.zeros((h, w, 3))
    q[..., 0], q[..., 1] = np.meshgrid(np.arange(w) * 0.1, np.arange(h) * 0.1)
    # a unit direction whose tile sums, made unit, meet it at a cosine of 1 + 2^-52
    r = np.broadcast_to([-0.9677334093782249, -0.2004977678984984, -0.15261943991810775],
                        (h, w, 3)).copy()
    tiles = PartTiles(inside, q, r, size=12)
    center, radius, axis, half, pixel = tile_bounds(inside, q, r, 12)
    assert np.isfinite(tiles.half).all() and (tiles.half == 0.0).all()
    np.testing.assert_array_equal(tiles.half, half)
    assert np.isfinite(tiles.part_half)
