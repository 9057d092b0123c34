"""Virtual-vertex kernels (exact sphere / cylinder / profile methods, screen refinement and
its tile culling, explosion maps) against their slow twins."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import compiled_only
from naive import (
    explosion_virtual,
    faces_behind,
    fill_extensions,
    fill_faces,
    fill_triangle,
    grid_sample,
    grid_sample_slope,
    map_coords,
    mirror_on_circle,
    nearest_filled_distance,
    nearest_filled_texel,
    part_candidates,
    plane_from_map,
    profile_one,
    refine_point,
    refine_walk,
    reflector_grid,
    scan,
    screen_plane,
    tile_bounds,
    vertex_coords,
)
from naive import fill_cracks as naive_fill_cracks
from naive import gather_corners as naive_gather_corners
from naive import joined as naive_joined
from naive import mirror_boxes as naive_mirror_boxes
from naive import mirror_rays as naive_mirror_rays
from naive import part_stencil as naive_part_stencil
from naive import part_views as naive_part_views

from reflectcli.camera import Camera
from reflectcli.raster.rasterize import FLAG_MIRROR, FLAG_SKIP
from reflectcli.scene import primitives
from reflectcli.virtual import circle, compose, direct, explosion, mapfill, refine, tiles
from reflectcli.virtual.mesh import weld
from reflectcli.virtual.tiles import PartTiles, joined


def circle_cases(rng, n=600):
    """Points around a unit sphere at the origin seen from an eye at distance ~4: visible,
    hidden behind it, inside it, on the line through the center and the eye (both sides),
    just off that line behind the sphere (a bracket of nearly pi), grazing its silhouette;
    more than two of circle.BLOCK, so blocks full and partial are both met."""
    eye = np.array([0.5, 0.8, 4.0])
    pts = list(rng.normal(size=(n, 3)) * 2.5)
    pts += [eye * 0.5, -eye, 2.0 * eye, np.array([0.1, 0.2, -0.3]), np.array([0.0, 0.0, -3.0])]
    side = np.cross(eye, [0.0, 1.0, 0.0])
    side /= np.linalg.norm(side)
    pts += [-2.0 * eye + 1e-9 * side, -2.0 * eye + 1e-5 * side]
    along = eye / np.linalg.norm(eye)
    pts += [1.0001 * side + t * along for t in (-2.0, -0.5, 0.0, 0.3)]
    return eye, np.array(pts)


def test_sphere_blocks_do_not_change_answers():
    """A point's virtual vertex is the same bytes whichever block (and lane) it is in."""
    eye, pts = circle_cases(np.random.default_rng(5))
    got, hidden = circle.sphere_virtual_vertices(pts, eye, np.zeros(3), 1.0)
    for i in range(0, len(pts), 7):
        one, one_h = circle.sphere_virtual_vertices(pts[i:i + 1], eye, np.zeros(3), 1.0)
        assert one.tobytes() == got[i:i + 1].tobytes() and one_h[0] == hidden[i]
    shifted, _ = circle.sphere_virtual_vertices(pts[3:], eye, np.zeros(3), 1.0)
    assert shifted.tobytes() == got[3:].tobytes()


@pytest.mark.parametrize("seed", range(2))
def test_sphere_virtual_vertices_match_twin(seed):
    eye, pts = circle_cases(np.random.default_rng(seed))
    center, radius = np.array([0.0, 0.0, 0.0]), 1.0
    got, hidden = circle.sphere_virtual_vertices(pts, eye, center, radius)
    for p, g, h in zip(pts, got, hidden, strict=True):
        want, want_h = mirror_on_circle(eye, p, center, radius)
        assert h == want_h, p
        np.testing.assert_allclose(g, want, atol=1e-6 * (1 + np.linalg.norm(p)))
    assert hidden.any() and not hidden.all()


@pytest.mark.parametrize("seed", range(2))
def test_cylinder_virtual_vertices_match_twin(seed):
    rng = np.random.default_rng(seed)
    eye, pts = circle_cases(rng)
    origin, axis = np.array([0.1, -1.0, 0.0]), np.array([0.2, 1.0, 0.1])
    got, hidden = circle.cylinder_virtual_vertices(pts, eye, origin, axis, 0.7)
    a = axis / np.linalg.norm(axis)
    for p, g, h in zip(pts, got, hidden, strict=True):
        want, want_h = mirror_on_circle(eye, p, origin, 0.7, a)
        assert h == want_h, p
        np.testing.assert_allclose(g, want, atol=1e-6 * (1 + np.linalg.norm(p)))
    assert hidden.any()


@pytest.mark.parametrize("seed", range(2))
def test_profile_virtual_vertices_match_twin(seed):
    rng = np.random.default_rng(seed)
    # a convex arc bulging toward +z (the viewer), normals roughly radial, not exactly
    ang = np.linspace(-1.0, 1.0, 9)
    profile = np.stack([np.sin(ang), np.cos(ang) - 1.0], 1)
    normals = np.stack([np.sin(ang * 1.05), np.cos(ang * 1.05)], 1)
    frame = np.eye(4)
    frame[:3, 3] = (0.2, -0.5, 0.1)
    eye = np.array([0.3, 1.0, 3.0])
    pts = np.concatenate([rng.normal(size=(120, 3)) * 2.0 + [0, 0, 1.5],
                          [[0.2, 0.0, -2.0], [3.0, 0.0, 0.5], [-0.1, 0.3, 0.4]]])
    got, hidden = direct.profile_virtual_vertices(pts, eye, profile, normals, frame)
    inv = np.linalg.inv(frame)
    e = inv[:3, :3] @ eye + inv[:3, 3]
    for p, g, h in zip(pts, got, hidden, strict=True):
        local = inv[:3, :3] @ p + inv[:3, 3]
        want, want_h = profile_one(local, e, profile, normals)
        assert h == want_h, p
        np.testing.assert_allclose(g, frame[:3, :3] @ want + frame[:3, 3], atol=1e-9)
    assert hidden.any() and not hidden.all()


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
        v = np.array(e) - cam.eye
        le, lp = np.sqrt(v @ v), np.sqrt((p - e) @ (p - e))
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


@pytest.fixture(scope="module")
def sphere_maps():
    m = primitives.uv_sphere(1.0, 12)
    mesh = weld(m.corners, m.normals)
    eye = np.array([0.4, 1.0, 6.0])
    return mesh, eye, explosion.build_explosion_maps(mesh, eye, np.zeros(3), 1.1, 30.0, 48,
                                                     layers=3)


@pytest.mark.parametrize("layers", [2, 5])
def test_explosion_layers_match_twin(layers):
    """_build_layers (every layer at once, a layer per thread) against the twins of its
    steps layer by layer: vertex coordinates, faces, the tally inside the circle, the
    extensions, and for each texel left empty an id of a filled texel at the nearest
    distance (ties between equally near ones are the transform's to break), unless no
    texel a lookup can reach was left empty (then the fill is skipped)."""
    m = primitives.uv_sphere(1.0, 10)
    mesh = weld(m.corners[:150], m.normals[:150])  # open: boundary edges give extensions
    eye = np.array([0.4, 1.0, 6.0])
    maps = explosion.build_explosion_maps(mesh, eye, np.zeros(3), 1.1, 30.0, 40, layers)
    assert len(maps.extensions)
    res, s = maps.res, maps.s
    c = np.arange(res) + 0.5 - res / 2.0
    circle_in = (c[None, :] ** 2 + c[:, None] ** 2) <= (s / 2.0) ** 2
    used = ~np.isnan(maps.layers[0].coords[:, 0])
    drawn = np.flatnonzero(used[mesh.faces].all(axis=1)
                           & (maps.front[mesh.faces].any(axis=1)))
    for layer in maps.layers:
        coords = vertex_coords(mesh.vertices, maps.normals, used, eye, maps.center,
                               layer.radius, maps.frame, res, s)
        np.testing.assert_allclose(layer.coords, coords, rtol=1e-12, atol=1e-9)
        ids = np.full((res, res), -1, np.int32)
        fill_faces(ids, layer.coords, mesh.faces, drawn)
        np.testing.assert_array_equal(layer.core, ids >= 0)
        assert layer.filled_before_extension == int(((ids >= 0) & circle_in).sum())
        fill_extensions(ids, layer.coords, maps.extensions, len(mesh.faces), res / 2.0,
                        explosion.EXTENSION_REACH * s)
        empty = ids < 0
        assert layer.empty_after_extension == int((empty & circle_in).sum())
        np.testing.assert_array_equal(layer.ids[~empty], ids[~empty])
        # texels a lookup can land in: their squares meet the disk of radius s / 2
        g = np.maximum(np.abs(c) - 0.5, 0.0)
        reachable = (g[None, :] ** 2 + g[:, None] ** 2) <= (s / 2.0 + 1e-6) ** 2
        if not (empty & reachable).any():
            continue  # nothing a lookup reaches is empty: the fill is skipped
        dist = nearest_filled_distance(empty)
        fy, fx = np.nonzero(~empty)
        for y, x in zip(*np.nonzero(empty), strict=True):
            near = (fy - y) ** 2 + (fx - x) ** 2 == round(dist[y, x] ** 2)
            assert layer.ids[y, x] in set(ids[fy[near], fx[near]]), (y, x)


def test_maps_for_lookups_of_a_patch_seen_from_behind():
    """A patch facing away from the eye fills no texel of any layer: built for lookups
    spread over a 200^2 map (the grown box the whole map), the build returns (the search
    for a nearest filled texel once never ended here) with the whole build's ids."""
    corners = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]],
                        [[1, 0, 0], [1, 1, 0], [0, 1, 0]]], float)
    normals = np.zeros_like(corners)
    normals[..., 2] = -1.0  # facing away from the eye at z = 6
    mesh = weld(corners, normals)
    eye, center = np.array([0.4, 1.0, 6.0]), np.array([0.5, 0.5, 0.0])
    pts = np.random.default_rng(0).normal(size=(200, 3)) * 3.0 + [0.5, 0.5, 4.0]
    whole = explosion.build_explosion_maps(mesh, eye, center, 0.5, 5.0, 200)
    some = explosion.build_explosion_maps(mesh, eye, center, 0.5, 5.0, 200, lookups=pts)
    for a, b in zip(whole.layers, some.layers, strict=True):
        assert (a.ids < 0).all() and (b.ids < 0).all()


@pytest.mark.parametrize("open_mesh", [False, True])
def test_maps_built_for_their_lookups_match_whole_maps_there(open_mesh):
    """build_explosion_maps with `lookups`: at every texel those points are looked up at
    (layers lo and lo + 1 of each, found by the twins' map_coords and radii), the ids and
    core of the whole build, and the same virtual vertices, bit for bit; on a closed
    sphere (extensions close the circle) and an open patch off the map's center (its
    extensions leave texels empty that lookups land in: the fill runs), points near and
    far, some flipped."""
    if open_mesh:
        corners = np.array([[[2, 0, 0], [2.5, 0, 0], [2.5, 0.5, 0]],
                            [[2, 0, 0], [2.5, 0.5, 0], [2, 0.5, 0]]], float)
        normals = np.zeros_like(corners)
        normals[..., 2] = 1.0
        normals[0, 0] = [0.3, 0.0, 1.0]  # a bend, so the patch's image is not a line
        normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    else:
        m = primitives.uv_sphere(1.0, 10)
        corners, normals = m.corners, m.normals
    mesh = weld(corners, normals)
    eye = np.array([0.4, 1.0, 6.0])
    rng = np.random.default_rng(12)
    pts = np.concatenate([rng.normal(size=(40, 3)) * 4.0,
                          [0.0, 0.0, 3.0] + rng.normal(size=(20, 3)) * 0.3])
    for flip_axis in (None, np.array([0.0, 0.0, 1.0])):
        whole = explosion.build_explosion_maps(mesh, eye, np.zeros(3), 1.1, 30.0, 40, 4)
        some = explosion.build_explosion_maps(mesh, eye, np.zeros(3), 1.1, 30.0, 40, 4,
                                              lookups=pts, flip_axis=flip_axis)
        radii = np.array([layer.radius for layer in whole.layers])
        flip = np.zeros(3) if flip_axis is None else flip_axis
        marked = np.zeros((len(radii), 40, 40), bool)
        for p in pts:
            d = p - whole.center
            d = -d if d @ flip < 0 else d
            tx, ty = map_coords(whole.frame, whole.res, whole.s, d)
            dist = np.linalg.norm(p - whole.center)
            lo = min(int(np.searchsorted(radii[1:], dist)), len(radii) - 2)
            x, y = (min(max(int(np.floor(t)), 0), 39) for t in (tx, ty))
            marked[[lo, lo + 1], y, x] = True
        for k, (a, b) in enumerate(zip(whole.layers, some.layers, strict=True)):
            np.testing.assert_array_equal(a.ids[marked[k]], b.ids[marked[k]])
            np.testing.assert_array_equal(a.core[marked[k]], b.core[marked[k]])
            np.testing.assert_array_equal(a.coords, b.coords)
        if open_mesh:  # a lookup lands where faces and extensions leave a texel empty
            used = ~np.isnan(whole.layers[0].coords[:, 0])
            drawn = np.flatnonzero(used[mesh.faces].all(axis=1)
                                   & whole.front[mesh.faces].any(axis=1))
            holes = False
            for k, layer in enumerate(whole.layers):
                ids = np.full((40, 40), -1, np.int32)
                fill_faces(ids, layer.coords, mesh.faces, drawn)
                fill_extensions(ids, layer.coords, whole.extensions, len(mesh.faces), 20.0,
                                explosion.EXTENSION_REACH * whole.s)
                holes |= bool((ids[marked[k]] < 0).any())
            assert holes
        none = np.full(len(pts), -1)
        got = explosion.virtual_vertices(some, pts, none, np.zeros((len(pts), 2)),
                                         np.zeros((len(mesh.vertices), 2)), flip_axis)
        want = explosion.virtual_vertices(whole, pts, none, np.zeros((len(pts), 2)),
                                          np.zeros((len(mesh.vertices), 2)), flip_axis)
        assert got[0].tobytes() == want[0].tobytes()
        np.testing.assert_array_equal(got[1], want[1])


def test_map_coords_and_vertex_coords_match_twin(sphere_maps):
    mesh, eye, maps = sphere_maps
    rng = np.random.default_rng(4)
    for d in list(rng.normal(size=(100, 3))) + [maps.frame[2], maps.frame[0]]:  # not -z: the rim
        np.testing.assert_allclose(explosion.map_coords(maps.frame, maps.res, maps.s, *d),
                                   map_coords(maps.frame, maps.res, maps.s, d), atol=1e-9)
    for layer in maps.layers:
        used = ~np.isnan(layer.coords[:, 0])
        want = vertex_coords(mesh.vertices, maps.normals, used, eye, maps.center,
                             layer.radius, maps.frame, maps.res, maps.s)
        np.testing.assert_allclose(layer.coords, want, atol=1e-9)


def test_fill_kernels_match_twin(sphere_maps):
    mesh, _, maps = sphere_maps
    rng = np.random.default_rng(5)
    for _ in range(40):  # single triangles, both windings, some degenerate or NaN
        tri = rng.uniform(-5, 30, (3, 2))
        if rng.random() < 0.1:
            tri[2] = tri[0] + 0.5 * (tri[1] - tri[0])
        if rng.random() < 0.05:
            tri[1, 0] = np.nan
        only_empty = bool(rng.random() < 0.5)
        ids = np.where(rng.random((24, 24)) < 0.3, 7, -1).astype(np.int32)
        want = ids.copy()
        mapfill._fill_triangle(ids, *tri.reshape(-1), 3, only_empty)
        fill_triangle(want, *tri, 3, only_empty)
        np.testing.assert_array_equal(ids, want)
    layer = maps.layers[1]
    f = mesh.faces
    drawn = rng.permutation(len(f))[: len(f) // 2].astype(np.int64)
    ids = np.full((maps.res, maps.res), -1, np.int32)
    want = ids.copy()
    explosion._fill_faces(ids, layer.coords, f, drawn)
    fill_faces(want, layer.coords, f, drawn)
    np.testing.assert_array_equal(ids, want)
    half = maps.res / 2.0
    explosion._fill_extensions(ids, layer.coords, maps.extensions, len(f), half,
                               explosion.EXTENSION_REACH * maps.s)
    fill_extensions(want, layer.coords, maps.extensions, len(f), half,
                    explosion.EXTENSION_REACH * maps.s)
    np.testing.assert_array_equal(ids, want)
    assert (ids >= len(f)).any()


def test_ids_at_marked_texels_match_the_fill_twins(sphere_maps):
    """mapfill._ids_at_marked (faces and quads sorted into cells, each marked texel tested
    alone) against drawing the whole map with the fill twins: at every marked texel the
    same id (the last face holding it, else the first quad) and core (a face holds it);
    True exactly when no marked texel is left empty. On the sphere's maps, with extra
    degenerate, NaN, tiny and map-wide triangles and quads, texels marked scattered, in
    clusters and on the map's edges, inside boxes of several sizes."""
    mesh, _, maps = sphere_maps
    rng = np.random.default_rng(8)
    res, half = maps.res, maps.res / 2.0
    reach = explosion.EXTENSION_REACH * maps.s
    for case in range(12):
        layer = maps.layers[case % len(maps.layers)]
        coords = layer.coords.copy()
        extra = np.concatenate([rng.uniform(-10, res + 10, (20, 2)),
                                coords[:5] + rng.normal(size=(5, 2)) * 0.3])
        extra[3] = np.nan
        coords = np.concatenate([coords, extra])
        v = len(layer.coords)
        faces = np.concatenate([mesh.faces, rng.integers(0, len(coords), (30, 3)),
                                [[v, v, v + 1], [v + 3, v + 4, v + 5]]]).astype(np.int64)
        drawn = rng.permutation(len(faces))[: int(len(faces) * rng.uniform(0.3, 1.0))]
        extensions = np.concatenate([maps.extensions, np.column_stack(
            [np.zeros(15, np.int64), rng.integers(0, len(coords), (15, 2))])])
        marks = rng.random((res, res)) < rng.choice([0.002, 0.02, 0.2])
        marks[rng.integers(0, res - 6):, :3] = True  # an edge, a cluster
        marks[0, rng.integers(0, res)] = True
        y0, y1, x0, x1 = mapfill._marked_box(marks)
        ids = np.full((res, res), -1, np.int32)
        core = np.zeros((res, res), bool)
        full = mapfill._ids_at_marked(ids, core, marks, coords, faces, drawn, extensions,
                                      len(faces), half, reach, y0, y1, x0, x1)
        want = np.full((res, res), -1, np.int32)
        fill_faces(want, coords, faces, drawn)
        want_core = want >= 0
        fill_extensions(want, coords, extensions, len(faces), half, reach)
        np.testing.assert_array_equal(ids[marks], want[marks])
        np.testing.assert_array_equal(core[marks], want_core[marks])
        assert (ids[~marks] == -1).all() and not core[~marks].any()
        assert full == bool((want[marks] >= 0).all())
        filled = marks & (want >= 0)  # only filled texels marked: none left empty
        again = np.full((res, res), -1, np.int32)
        assert mapfill._ids_at_marked(again, core, filled, coords, faces, drawn, extensions,
                                      len(faces), half, reach, *mapfill._marked_box(filled))
        np.testing.assert_array_equal(again[filled], want[filled])
        hole = mapfill._hole_box(ids, marks, y0, y1, x0, x1)
        empty = np.argwhere(marks & (ids < 0))
        if len(empty):
            assert hole == (empty[:, 0].min(), empty[:, 0].max(), empty[:, 1].min(),
                            empty[:, 1].max())
        else:
            assert hole[0] > hole[1]


def test_plane_and_screen_lookups_match_twin(sphere_maps):
    mesh, _, maps = sphere_maps
    rng = np.random.default_rng(6)
    layer = maps.layers[0]
    ids = layer.ids.copy()
    ids[:2] = -1  # some empty texels
    for t in list(rng.uniform(-2, maps.res + 2, (300, 2))):
        p, n = explosion._plane_from_map(ids, layer.coords, mesh.vertices, maps.normals,
                                         mesh.faces, maps.extensions, *t)
        wp, wn = plane_from_map(ids, layer.coords, mesh.vertices, maps.normals, mesh.faces,
                                maps.extensions, t)
        np.testing.assert_allclose(p, wp, atol=1e-8)
        np.testing.assert_allclose(n, wn, atol=1e-8)
    screen = rng.uniform(0, 50, (len(mesh.vertices), 2))
    screen[mesh.faces[0, 2]] = screen[mesh.faces[0, 0]]  # a degenerate face on screen
    for f in list(rng.integers(0, len(mesh.faces), 100)) + [0]:
        s = rng.uniform(0, 50, 2)
        p, n = explosion._screen_plane(mesh.faces, f, screen, mesh.vertices, maps.normals, *s)
        wp, wn = screen_plane(mesh.faces, f, screen, mesh.vertices, maps.normals, s)
        np.testing.assert_allclose(p, wp, atol=1e-8, rtol=1e-8)
        np.testing.assert_allclose(n, wn, atol=1e-8)


@pytest.mark.parametrize("flip", [False, True])
def test_explosion_lookup_matches_twin(sphere_maps, flip):
    mesh, eye, maps = sphere_maps
    rng = np.random.default_rng(7)
    n = 200
    pts = rng.normal(size=(n, 3)) * 4.0
    pts[:3] = [[0.0, 0.0, 40.0], [0.0, 0.0, 1.05], [0.5, 0.5, 0.0]]  # beyond far, near, inside
    hidden_face = np.where(rng.random(n) < 0.2, rng.integers(0, len(mesh.faces), n), -1)
    hidden_screen = rng.uniform(0, 50, (n, 2))
    screen = rng.uniform(0, 50, (len(mesh.vertices), 2))
    flip_axis = np.array([0.0, 0.0, 1.0]) if flip else None
    got, flags = explosion.virtual_vertices(maps, pts, hidden_face, hidden_screen, screen,
                                            flip_axis)
    ids = np.stack([layer.ids for layer in maps.layers])
    want, unreflected = explosion_virtual(
        pts, mesh.vertices, maps.normals, mesh.faces, maps.extensions, ids,
        np.stack([layer.coords for layer in maps.layers]),
        np.array([layer.radius for layer in maps.layers]), maps.center,
        np.zeros(3) if flip_axis is None else flip_axis, maps.frame, maps.res, maps.s,
        hidden_face, hidden_screen, screen, np.stack([layer.core for layer in maps.layers]))
    np.testing.assert_allclose(got, want, atol=1e-8, rtol=1e-9)
    np.testing.assert_array_equal(flags, (hidden_face >= 0) | unreflected)
    assert not unreflected.all() and (unreflected.any() or flip)


def test_nearest_filled_matches_twin():
    """The feature transform behind _fill_nearest names, for every texel, a filled texel at
    the least distance (ties may go either way), on sparse, dense, one-row and one-column
    maps and a map with one filled texel."""
    rng = np.random.default_rng(8)
    cases = [rng.random(tuple(rng.integers(1, 30, 2))) < p for p in (0.3, 0.8, 0.97)
             for _ in range(10)]
    cases += [rng.random((1, 25)) < 0.7, rng.random((25, 1)) < 0.7,
              np.arange(400).reshape(20, 20) != 137]
    for empty in cases:
        if empty.all():
            continue
        h, w = empty.shape
        rows = np.empty((h, w), np.int32)
        cols = np.empty((h, w), np.int32)
        explosion._nearest_filled(empty, rows, cols)
        assert not empty[rows, cols].any()
        got = np.hypot(rows - np.arange(h)[:, None], cols - np.arange(w)[None, :])
        np.testing.assert_allclose(got, nearest_filled_distance(empty), rtol=0, atol=1e-12)


def test_nearest_near_marked_texels_matches_twin():
    """_nearest_in_box answers as the whole map's rule would (nearest, then least column,
    then least row), or not at all when a texel outside its box could be as near; and
    _fill_marked_nearest fills the marked empty texels as _nearest_filled does over the
    whole map (which the rule matches), or leaves the layer alone."""
    rng = np.random.default_rng(13)
    answered = declined = 0
    for _ in range(60):
        h, w = (int(v) for v in rng.integers(8, 40, 2))
        layer = np.where(rng.random((h, w)) < rng.choice([0.02, 0.1, 0.5]),
                         rng.integers(0, 50, (h, w)), -1).astype(np.int32)
        y0, x0 = int(rng.integers(0, h)), int(rng.integers(0, w))
        y1, x1 = int(rng.integers(y0, h)), int(rng.integers(x0, w))
        for y, x in zip(*np.nonzero(layer[y0:y1 + 1, x0:x1 + 1] < 0), strict=True):
            y, x = int(y + y0), int(x + x0)
            got = mapfill._nearest_in_box(layer, y0, y1, x0, x1, y, x)
            want = nearest_filled_texel(layer, y, x)
            if got != (-1, -1):
                assert got == want
                answered += 1
                continue
            declined += 1
            sides = [(y - y0 + 1) ** 2 if y0 > 0 else np.inf,
                     (y1 + 1 - y) ** 2 if y1 < h - 1 else np.inf,
                     (x - x0 + 1) ** 2 if x0 > 0 else np.inf,
                     (x1 + 1 - x) ** 2 if x1 < w - 1 else np.inf]
            assert want is None or (want[0] - y) ** 2 + (want[1] - x) ** 2 >= min(sides)
        marks = rng.random((h, w)) < 0.2
        reach = np.ones((h, w), bool)
        filled = layer.copy()
        if mapfill._fill_marked_nearest(filled, marks, reach, y0, y1, x0, x1, 4):
            empty = layer < 0
            rows = np.empty((h, w), np.int32)
            cols = np.empty((h, w), np.int32)
            if not empty.all():
                mapfill._nearest_filled(empty, rows, cols)
            box = np.zeros((h, w), bool)
            box[y0:y1 + 1, x0:x1 + 1] = True
            sel = marks & box & empty
            np.testing.assert_array_equal(filled[sel], layer[rows[sel], cols[sel]])
            np.testing.assert_array_equal(filled[~sel], layer[~sel])
        else:
            np.testing.assert_array_equal(filled, layer)
    assert answered > 100 and declined > 10
    # a layer with no filled texel (a part seen only from behind), the box the whole map or
    # a part of it: no answer (the whole layer's build takes over), and no endless search
    empty = np.full((12, 12), -1, np.int32)
    marks = np.zeros((12, 12), bool)
    marks[5, 5] = True
    for box in ((0, 11, 0, 11), (5, 5, 5, 5), (2, 9, 0, 11)):
        assert mapfill._nearest_in_box(empty, *box, 5, 5) == (-1, -1)
        assert not mapfill._fill_marked_nearest(empty.copy(), marks, np.ones((12, 12), bool),
                                                5, 5, 5, 5, 48)


def test_mirror_boxes_match_twin():
    rng = np.random.default_rng(3)
    surface = rng.integers(-1, 4, (23, 31)).astype(np.int32)
    surface[surface == 5] = 0
    surface[:, :] = np.where(surface == 4, 1, surface)  # mirror 2 (surface 4) absent
    got = compose.mirror_boxes(surface, 2, 3)
    want = naive_mirror_boxes(surface, 2, 3)
    for g, x in zip(got, want, strict=True):
        np.testing.assert_array_equal(g, x)
    assert got[0][2] == 0 and got[0][0] > 0


def test_gather_corners_match_twin():
    rng = np.random.default_rng(4)
    virtual = rng.normal(size=(40, 3)) * 5
    hidden = rng.random(40) < 0.6
    corner_index = rng.integers(0, 40, (70, 3))
    surface = rng.integers(0, 6, 70)
    corners = np.empty((70, 3, 3), np.float32)
    flags = np.empty(70, np.uint8)
    compose.gather_corners(virtual, hidden, corner_index, surface, 4, corners, flags)
    want_corners, want_flags = naive_gather_corners(virtual, hidden, corner_index, surface, 4)
    assert corners.tobytes() == want_corners.tobytes()
    np.testing.assert_array_equal(flags, want_flags)
    assert (flags & FLAG_SKIP).any() and (flags & FLAG_MIRROR).any()


@pytest.mark.parametrize("seed", range(3))
def test_fill_cracks_match_twin(seed):
    rng = np.random.default_rng(seed)
    h, w = 19, 23
    covered = rng.random((h, w)) < 0.8
    stencil = covered | (rng.random((h, w)) < 0.7)
    stencil[:2] = False  # a box that is not the whole image
    # the pass's triangle ids: drawn only on the stencil; elsewhere whatever an earlier
    # pass left (ids or -1), which must not count
    triangle = np.where(covered, rng.integers(0, 50, (h, w)), -1).astype(np.int32)
    stale = ~stencil & (rng.random((h, w)) < 0.5)
    triangle[stale] = rng.integers(0, 50, int(stale.sum()))
    covered &= stencil
    colors = rng.random((h, w, 3)).astype(np.float32)
    want = colors.copy()
    naive_fill_cracks(want, covered, stencil)
    ys, xs = np.nonzero(stencil)
    compose.fill_cracks(colors, triangle, stencil, ys.min(), ys.max() + 1, xs.min(),
                        xs.max() + 1)
    assert colors.tobytes() == want.tobytes()


@compiled_only
def test_mirror_rays_match_reflector_grid():
    """R at mirror pixels from barycentrics recovered in the kernel: the very bytes of
    reflector_grid from the buffers' own b1, b2; NaN at the box's other pixels."""
    from reflectcli.raster.rasterize import rasterize as fast_rasterize

    cam = Camera(np.array([0.0, 0.4, 3.0]), np.zeros(3), np.array([0.0, 1.0, 0.0]), 50.0, 40,
                 30, 0.1, 100.0)
    sphere = primitives.uv_sphere(1.0, 12)
    corners = sphere.corners.astype(np.float32)
    normals = sphere.normals.astype(np.float32)
    m = cam.clip_from_world()
    buffers = fast_rasterize(corners, np.zeros(len(corners), np.uint8), m, 40, 30)
    mirror = np.zeros((30, 40), bool)
    mirror[:, 12:] = True  # a part of the sphere only
    tri = buffers.triangle
    masked = np.where(mirror, tri, -1).astype(np.int32)
    _, want = refine.reflector_grid(masked, buffers.b1, buffers.b2, corners, normals, cam.eye)
    r = np.full((30, 40, 3), 7.0)
    refine.mirror_rays(tri, mirror, corners, m, corners, normals, np.asarray(cam.eye, float),
                       3, 27, 5, 38, r)
    box = (slice(3, 27), slice(5, 38))
    assert r[box].tobytes() == want[box].tobytes()
    assert (r[:3] == 7.0).all() and (r[:, 38:] == 7.0).all()
    assert np.isfinite(r[box]).sum() > 300
    # and the slow twin, barycentrics worked in float64 from the pixel centers
    slow = naive_mirror_rays(tri, mirror, corners, m, corners, normals, np.asarray(cam.eye),
                             (3, 27, 5, 38))
    assert np.array_equal(np.isnan(r[box]), np.isnan(slow[box]))
    np.testing.assert_allclose(r[box], slow[box], atol=2e-5)  # float32 barycentrics


def test_part_stencil_matches_twin():
    rng = np.random.default_rng(11)
    triangle = rng.integers(-1, 60, (21, 27)).astype(np.int32)
    surface = rng.integers(-1, 5, (21, 27)).astype(np.int32)
    faces = np.array([0, 3, 4, 9, 29])  # of the reflector's 30 faces, triangles 20 .. 49
    in_part = np.zeros(31, bool)
    in_part[faces] = True
    out = np.empty((21, 27), np.bool_)
    compose.part_stencil(triangle, surface, 3, 20, in_part, out)
    want = naive_part_stencil(triangle, surface, 3, 20, faces, 30)
    np.testing.assert_array_equal(out, want)
    assert want.sum() > 5


def test_faces_behind_match_twin():
    """PartView.faces_behind (the hidden map's faces of points behind the reflector alone)
    against its twin: points on and off the image, on its edges, behind the eye, deeper and
    shallower than the depth, NaN and infinite."""
    from reflectcli.virtual.view import PartView, PointsOnScreen

    rng = np.random.default_rng(4)
    h, w, count = 23, 31, 12
    triangle = rng.integers(-1, count, (h, w)).astype(np.int32)
    local = np.full(count + 1, -1, np.int32)
    local[[1, 4, 5, 9]] = np.arange(4)
    depth = rng.uniform(1.0, 3.0, (h, w))
    depth[0, :5] = np.inf  # no reflector there
    n = 400
    screen = np.column_stack([rng.uniform(-3, w + 3, n), rng.uniform(-3, h + 3, n),
                              rng.uniform(-1.0, 4.0, n)])
    screen[:40, :2] = np.floor(screen[:40, :2])  # on pixel edges
    edges = [[0.0, 0.0, 5.0], [w, 3.0, 5.0], [w - 1e-9, 3.0, 5.0], [3.0, h, 5.0],
             [-1e-12, 2.0, 5.0], [np.nan, 2.0, 5.0], [2.0, np.inf, 5.0], [2.0, 2.0, np.nan],
             [2.0, 2.0, np.inf], [2.0, 2.0, 0.0], [-np.inf, 1.0, 5.0], [1.0, 1.0, -2.0]]
    screen = np.concatenate([screen, edges])
    view = PartView(np.zeros((h, w), np.int16), 0, triangle, local, None, PointsOnScreen())
    got = view.faces_behind(screen, depth)
    np.testing.assert_array_equal(got, faces_behind(screen, depth, triangle, local))
    assert (got >= 0).sum() > 20 and (got < 0).sum() > 20


def test_part_views_match_twin():
    """view.part_views (one pass, every part, one owner plane) against its twin part by
    part: each part's face under each pixel (PartView.hidden_faces), its pixels, and its
    tiles as np.unique of the pixels' tile ids."""
    from reflectcli.virtual.view import PartView, PointsOnScreen, part_views

    rng = np.random.default_rng(12)
    h, w, count, size = 37, 50, 40, 12
    triangle = rng.integers(-1, count, (h, w)).astype(np.int32)
    triangle[:, :20] = -1  # tiles with no pixel of any part
    faces = [np.array([0, 5, 7]), np.arange(10, 30), np.array([39])]
    local = np.full((len(faces), count + 1), -1, np.int32)
    part_of = np.full(count + 1, -1, np.int16)
    for p, f in enumerate(faces):
        local[p, f] = np.arange(len(f))
        part_of[f] = p
    owner = np.empty((h, w), np.int16)
    marks = np.zeros((len(faces), h // size + 1, w // size + 1), np.bool_)
    part_views(triangle, part_of, size, owner, marks)
    ys, xs = np.indices((h, w))
    for p, (want, want_inside, want_tiles) in enumerate(naive_part_views(triangle, local,
                                                                          size)):
        view = PartView(owner, p, triangle, local[p], None, PointsOnScreen())
        np.testing.assert_array_equal(view.hidden_faces(ys, xs), want)
        np.testing.assert_array_equal(owner == p, want_inside)
        np.testing.assert_array_equal(np.flatnonzero(marks[p]), want_tiles)


def test_pass_labels_match_twin():
    from naive import pass_labels as naive_pass_labels

    rng = np.random.default_rng(8)
    h, w = 21, 17
    surface = rng.integers(-1, 9, (h, w)).astype(np.int32)  # objects 0..3, mirrors 4..8
    depth = rng.uniform(0.5, 9.0, (h, w)).astype(np.float32)
    label_of = np.array([2, 0, 1, 3, 0], np.uint8)  # mirror 1 and 4 not drawn together
    labels = np.full((h, w), 99, np.uint8)
    stencil = np.zeros((h, w), np.bool_)
    floor = np.full((h, w), -1.0, np.float32)
    compose.pass_labels(surface, depth, 4, label_of, 2, h - 3, 1, w - 2, labels, stencil,
                        floor)
    want = naive_pass_labels(surface, depth, 4, label_of)
    box = (slice(2, h - 3), slice(1, w - 2))
    for got, expect in zip((labels, stencil, floor), want, strict=True):
        assert got[box].tobytes() == expect[box].tobytes()
    assert labels[0, 0] == 99 and floor[-1, -1] == -1.0  # outside the box: untouched
    assert set(np.unique(labels[box])) == {0, 1, 2, 3}


@pytest.mark.parametrize("seed", range(3))
def test_compose_passes_match_twin(seed):
    """Cracks filled within each label only (a neighbour of another label never counts as
    covered), then each label's reflectance added: the twins one label at a time."""
    from naive import compose_passes as naive_compose_passes

    rng = np.random.default_rng(seed)
    h, w = 19, 23
    labels = rng.integers(0, 4, (h, w)).astype(np.uint8)
    labels[:2] = 0
    labels[5:9, 4:12] = 2  # wide runs of one label: cracks to fill
    triangle = np.where(rng.random((h, w)) < 0.7, rng.integers(0, 50, (h, w)), -1)
    triangle = triangle.astype(np.int32)
    colors = rng.random((h, w, 3)).astype(np.float32)
    rgb = rng.random((h, w, 3)).astype(np.float32)
    reflectance = rng.random((3, 3)).astype(np.float32)
    labels[:, -2:] = 0  # and a box short of the image's right edge
    want_colors = colors.copy()
    want = naive_compose_passes(rgb, want_colors, triangle, labels, reflectance)
    got = rgb.copy()
    ys, xs = np.nonzero(labels)
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    # outside the box the buffers hold another frame's or pass's labels and triangles:
    # never read (a crack on the box's edge must not be filled from them)
    outside = np.ones((h, w), bool)
    outside[y0:y1, x0:x1] = False
    labels[outside] = rng.integers(1, 4, outside.sum())
    triangle[outside] = rng.integers(0, 50, outside.sum())
    compose.compose_passes(got, colors, triangle, labels, reflectance, y0, y1, x0, x1)
    assert colors.tobytes() == want_colors.tobytes()
    assert got.tobytes() == want.tobytes()
    assert not np.array_equal(got, rgb)


def test_spheres_together_give_each_sphere_s_bytes():
    """Several spheres' points in one call (spheres_virtual_vertices): each point the very
    bytes of its sphere's call alone, with empty spheres and spheres shorter than a block."""
    eye, pts = circle_cases(np.random.default_rng(6))
    rng = np.random.default_rng(7)
    more = rng.normal(size=(3 * circle.BLOCK + 11, 3)) * 3.0
    centers = np.array([[0.0, 0.0, 0.0], [0.5, -0.2, 0.1], [9.0, 9.0, 9.0], [-0.3, 0.2, 0.4]])
    radii = np.array([1.0, 0.7, 0.5, 1.2])
    parts = [pts, more[:circle.BLOCK + 5], np.zeros((0, 3)), more[circle.BLOCK + 5:]]
    points = np.ascontiguousarray(np.concatenate(parts))
    starts = np.cumsum([0] + [len(p) for p in parts])
    out = np.empty_like(points)
    hidden = np.empty(len(points), np.bool_)
    circle.spheres_virtual_vertices(points, eye, centers, radii, starts, out, hidden,
                                    circle.block_scratch())
    for s, part in enumerate(parts):
        want, want_hidden = circle.sphere_virtual_vertices(part, eye, centers[s], radii[s])
        assert out[starts[s]:starts[s + 1]].tobytes() == want.tobytes()
        assert hidden[starts[s]:starts[s + 1]].tobytes() == want_hidden.tobytes()


def test_part_labels_match_twin():
    """A reflector's part labels, stencil, depth floor and per-label boxes in its box, on
    random buffers (faces of other surfaces, ids outside the reflector's faces, labels
    with no pixel), against the twin; nothing outside the box is written."""
    from naive import part_labels as naive_part_labels

    from reflectcli.virtual.partpasses import part_labels

    rng = np.random.default_rng(12)
    h, w, first, count = 40, 56, 30, 50
    triangle = rng.integers(-1, first + count + 20, (h, w)).astype(np.int32)
    surface = rng.integers(0, 4, (h, w)).astype(np.int32)
    surface[5:30, 8:40] = 2  # the reflector's pixels lie in its box
    surface[:5] = np.where(surface[:5] == 2, 3, surface[:5])
    surface[30:] = np.where(surface[30:] == 2, 3, surface[30:])
    surface[:, :8] = np.where(surface[:, :8] == 2, 3, surface[:, :8])
    surface[:, 40:] = np.where(surface[:, 40:] == 2, 3, surface[:, 40:])
    depth = rng.uniform(1, 9, (h, w)).astype(np.float32)
    label_of = np.zeros(count + 1, np.uint8)
    label_of[:count] = rng.integers(1, 6, count)
    label_of[label_of == 4] = 3  # label 4 has no face: its box stays zero
    want = naive_part_labels(triangle, surface, 2, first, label_of, depth)
    labels = np.full((h, w), 77, np.uint8)
    stencil = np.ones((h, w), np.bool_)
    floor = np.full((h, w), -1.0, np.float32)
    boxes = np.empty((int(label_of.max()), 4), np.int64)
    part_labels(triangle, surface, 2, first, label_of, 5, 30, 8, 40, depth, labels, stencil,
                floor, boxes)
    np.testing.assert_array_equal(boxes, want[3])
    assert not boxes[3].any()
    for got, wanted, outside in zip((labels, stencil, floor), want[:3], (77, True, -1.0),
                                    strict=True):
        np.testing.assert_array_equal(got[5:30, 8:40], wanted[5:30, 8:40])
        inside = np.zeros((h, w), bool)
        inside[5:30, 8:40] = True
        assert (got[~inside] == outside).all()


def _mask_frame(threads):
    """The mask scene at 160 x 160 (several parts seen), prepared at `threads`."""
    import numba
    from conftest import SCENES

    from reflectcli.camera import camera_from_config
    from reflectcli.loading import load_config
    from reflectcli.scene.build import build_scene
    from reflectcli.techniques.virtual.technique import Virtual

    numba.set_num_threads(threads)
    path = str(SCENES / "mask.toml")
    cfg, _ = load_config(path, ["camera.width=160", "camera.height=160"], "virtual")
    scene = build_scene(cfg, path)
    cam = camera_from_config(cfg.camera, 0)
    technique = Virtual(cfg.technique)
    return cfg, scene, cam, technique, technique.prepare(scene)


@compiled_only
@pytest.mark.parametrize("threads", [1, 2])
def test_parts_together_give_each_part_s_answers(threads):
    """A reflector's parts worked stage by stage (parts_vertices: tile scans, maps,
    lookups and refinement each in one region for all parts; its arrays fresh or in a
    workspace used twice) give each part the very bytes of its own call
    (ExplosionPart.__call__, whose stages are held to their twins)."""
    import numba

    from reflectcli.raster.primary import render_primary
    from reflectcli.raster.rasterize import RasterWorkspace
    from reflectcli.virtual.dispatch import reflector_parts
    from reflectcli.virtual.parts import parts_vertices

    before = numba.get_num_threads()
    try:
        cfg, scene, cam, technique, state = _mask_frame(threads)
        primary = render_primary(scene, 0, cam)
        tess = state.reflected.get(scene.geometry(0), scene.n_objects, 0,
                                   cfg.technique.tessellation, closed=state.closed)
        parts = [fn for _, fn in reflector_parts(cfg.technique, scene, primary, 0, cam,
                                                 state.scene_points, state.shapes,
                                                 state.views)]
        assert len(parts) > 4
        want = [part(tess.points, tess.corner_index) for part in parts]
        ws = RasterWorkspace(outputs=True)
        for workspace in (None, ws, ws):
            virtual, flags = parts_vertices(parts, tess.points, tess.corner_index,
                                            workspace)
            assert virtual.shape == (len(parts), len(tess.points), 3)
            for p, (v, f) in enumerate(want):
                assert virtual[p].tobytes() == v.tobytes()
                assert flags[p].tobytes() == f.tobytes()
    finally:
        numba.set_num_threads(before)


@compiled_only
@pytest.mark.parametrize("threads", [1, 2])
def test_part_passes_together_give_the_frame_part_by_part(threads, monkeypatch):
    """A mesh reflector of several parts drawn together (partpasses.draw_parts: one label
    image, rasterize_passes, one shading, compose_passes) gives the frame's bytes drawn
    part by part (draw_virtual and add_reflection, each part's stencil), frame after
    frame."""
    import numba

    import reflectcli.techniques.virtual.technique as module

    before = numba.get_num_threads()
    try:
        _, scene, cam, technique, state = _mask_frame(threads)
        together = [technique.render(state, 0, cam).rgb.copy() for _ in range(2)]
        assert together[0].tobytes() == together[1].tobytes()
        monkeypatch.setattr(module, "explosion_group", lambda *args, **kwargs: None)
        apart = technique.render(state, 0, cam)
        assert apart.stats["reflector_parts"] > 4
        assert apart.rgb.tobytes() == together[0].tobytes()
    finally:
        numba.set_num_threads(before)
