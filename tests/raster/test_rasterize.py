"""The numba rasterizer against a slow, obviously correct float64 reference.

The reference visits every pixel center and every triangle: clip-space transform, screen
positions, inside test by screen-space edge functions (edges inclusive, as the rasterizer),
perspective-correct barycentrics and depth through 1/w, nearest wins with a strict less-than
in triangle order. Pixels whose center lies within 1e-6 px of a covering triangle's edge, or
where two covering triangles' depths tie to 1e-6 relative, may go either way; they are
counted, bounded, and left out of the exact comparison.
"""

from __future__ import annotations

import numba
import numpy as np
import pytest
from naive import fill_fixed, ray_triangle, reference
from naive import stencil_box as naive_stencil_box

from reflectcli.camera import Camera
from reflectcli.raster.rasterize import (
    CULL_BACK,
    CULL_FRONT,
    CULL_NONE,
    FLAG_CULL_BACK,
    FLAG_CULL_FRONT,
    FLAG_MIRROR,
    FLAG_SKIP,
    rasterize,
)
from reflectcli.raster.rasterize.constants import _BLOCK
from reflectcli.raster.rasterize.fixed import _subpixel_bits
from reflectcli.raster.rasterize.rows import _fill
from reflectcli.raster.rasterize.setup import _setup

W, H = 40, 30
def camera(w=W, h=H, near=0.5, far=50.0) -> Camera:
    return Camera(np.array([0.3, 1.0, 4.0]), np.array([-0.2, 0.6, -1.0]),
                  np.array([0.1, 1.0, 0.0]), 60.0, w, h, near, far)


def clip_from_world(cam: Camera) -> np.ndarray:
    return cam.projection_matrix() @ cam.view_matrix()


def random_triangles(cam: Camera, n: int, rng, depth=(1.0, 12.0), spread=1.1,
                     size=(0.4, 1.5)) -> np.ndarray:
    """Triangles with every corner in eye-space depth range `depth` (in front of near),
    scattered over (and a little beyond) the view, as world-space float32 (n, 3, 3)."""
    right, up, back = cam.basis()
    t = np.tan(np.radians(cam.fov_y) / 2)
    center = rng.uniform(-1, 1, (n, 1, 2)) * spread
    xy = center + rng.uniform(*size, (n, 1, 1)) * rng.uniform(-1, 1, (n, 3, 2))
    z = rng.uniform(*depth, (n, 1)) * rng.uniform(0.85, 1.15, (n, 3))
    z = np.clip(z, *depth)
    world = (cam.eye + z[..., None] * (-back + xy[..., :1] * t * cam.aspect * right
                                       + xy[..., 1:] * t * up))
    return world.astype(np.float32)


@pytest.mark.parametrize("seed", range(8))
def test_matches_reference_on_random_scenes(seed):
    rng = np.random.default_rng(seed)
    cam = camera()
    corners = random_triangles(cam, 20, rng)
    flags = np.where(rng.random(20) < 0.25, FLAG_MIRROR, 0).astype(np.uint8)
    m = clip_from_world(cam)
    got = rasterize(corners, flags, m, W, H)
    tri, b1, b2, depth, ambiguous = reference(corners, flags, m, W, H)
    assert (tri >= 0).mean() > 0.3  # not a vacuous comparison: much of the view is covered
    agree = got.triangle == tri
    # only ambiguous pixels may differ, and they are few
    assert np.all(agree | ambiguous)
    assert ambiguous.sum() <= 0.01 * W * H
    assert agree.mean() >= 0.99
    both = agree & (tri >= 0)
    np.testing.assert_allclose(got.depth[both], depth[both], rtol=1e-4)
    np.testing.assert_allclose(got.b1[both], b1[both], atol=1e-4)
    np.testing.assert_allclose(got.b2[both], b2[both], atol=1e-4)
    assert np.all(np.isinf(got.depth[got.triangle < 0]))
    assert np.all(got.b1[got.triangle < 0] == 0) and np.all(got.b2[got.triangle < 0] == 0)


def test_reference_agreement_over_many_scenes():
    """Aggregate over 40 scenes: the figure the per-scene test bounds, measured overall."""
    cam = camera()
    m = clip_from_world(cam)
    total = agree_n = amb_n = 0
    for seed in range(100, 140):
        rng = np.random.default_rng(seed)
        corners = random_triangles(cam, 20, rng)
        flags = np.zeros(20, np.uint8)
        got = rasterize(corners, flags, m, W, H)
        tri, _, _, _, ambiguous = reference(corners, flags, m, W, H)
        assert np.all((got.triangle == tri) | ambiguous)
        total += W * H
        agree_n += int((got.triangle == tri).sum())
        amb_n += int(ambiguous.sum())
    assert agree_n / total >= 0.999
    assert amb_n / total <= 0.002


def straddling_triangle(cam: Camera, rng) -> np.ndarray:
    """Eye space: corner 0 between the eye and the near plane (or behind the eye), near the
    view axis; corners 1 and 2 well in front, inside the view. World space, (1, 3, 3)."""
    tan = np.tan(np.radians(cam.fov_y) / 2)
    za = rng.uniform(-1.5, 0.8)
    pts = [np.array([*rng.uniform(-0.5, 0.5, 2), -za])]
    for _ in range(2):
        z = rng.uniform(2.0, 6.0)
        x, y = rng.uniform(-0.9, 0.9, 2)
        pts.append(np.array([x * tan * cam.aspect * z, y * tan * z, -z]))
    pts = np.array(pts)[rng.permutation(3)]
    world = np.c_[pts, np.ones(3)] @ np.linalg.inv(cam.view_matrix()).T
    return world[None, :, :3].astype(np.float32)


@pytest.mark.parametrize("seed", range(6))
def test_near_plane_clipping_matches_ray_casting(seed):
    """A triangle straddling the near plane covers exactly the pixels whose center ray meets
    it at depth >= near (rays with t = eye-space depth), at the depth of that hit."""
    rng = np.random.default_rng(seed)
    cam = camera(w=64, h=48, near=1.0)
    d = cam.pixel_directions(1).reshape(-1, 3)
    origins = np.broadcast_to(cam.eye, d.shape)
    while True:  # draw until the case is not vacuous (decided by ray casting alone)
        corners = straddling_triangle(cam, rng)
        t, u, v = ray_triangle(origins, d, corners[0].astype(np.float64))
        w = 1 - u - v
        inside = (u >= 0) & (v >= 0) & (w >= 0)
        hit = inside & (t >= cam.near) & (t <= cam.far)
        # drawn somewhere, and near clipping removes part of it
        if hit.sum() > 50 and (inside & (t > 0) & (t < cam.near)).sum() > 20:
            break
    got = rasterize(corners, np.zeros(1, np.uint8), clip_from_world(cam), cam.width, cam.height)
    # within 1e-6 of an edge or of the near plane: either answer is fine
    marginal = ((np.minimum(np.minimum(np.abs(u), np.abs(v)), np.abs(w)) < 1e-6)
                | (np.abs(t - cam.near) < 1e-6 * cam.near))
    hit, marginal = hit.reshape(got.triangle.shape), marginal.reshape(got.triangle.shape)
    drawn = got.triangle == 0
    assert np.all((drawn == hit) | marginal)
    assert marginal.sum() <= 0.01 * drawn.size
    both = drawn & hit
    tt = t.reshape(drawn.shape)
    np.testing.assert_allclose(got.depth[both], tt[both], rtol=1e-5)
    np.testing.assert_allclose(got.b1[both], u.reshape(drawn.shape)[both], atol=1e-4)
    np.testing.assert_allclose(got.b2[both], v.reshape(drawn.shape)[both], atol=1e-4)
    assert got.depth[drawn].min() >= cam.near * (1 - 1e-6)


def test_deterministic_across_thread_counts():
    rng = np.random.default_rng(7)
    cam = camera(w=160, h=120)
    corners = random_triangles(cam, 3000, rng)
    # exact duplicates (depth ties resolved by triangle order) and a few near-plane crossers
    corners = np.concatenate([corners, corners[::7]])
    corners[::50, 0] = cam.eye - 0.2 * (cam.target - cam.eye)
    flags = np.where(rng.random(len(corners)) < 0.1, FLAG_MIRROR, 0).astype(np.uint8)
    m = clip_from_world(cam)
    before = numba.get_num_threads()
    try:
        results = []
        for threads in (1, 2, 1):
            numba.set_num_threads(threads)
            results.append(rasterize(corners, flags, m, cam.width, cam.height))
    finally:
        numba.set_num_threads(before)
    a = results[0]
    for b in results[1:]:
        for name in ("triangle", "b1", "b2", "depth"):
            x, y = getattr(a, name), getattr(b, name)
            assert x.dtype == y.dtype
            assert x.tobytes() == y.tobytes(), name
    assert (a.triangle >= 0).mean() > 0.9


@pytest.mark.parametrize("mirror_first", [True, False])
def test_mirror_wins_coplanar_tie(mirror_first):
    cam = camera(w=64, h=48)
    right, up, back = cam.basis()
    center = cam.eye - 5.0 * back
    quad = np.array([center - 2 * right - 2 * up, center + 2 * right - 2 * up,
                     center + 2 * right + 2 * up, center - 2 * right + 2 * up])
    wall = np.array([quad[[0, 1, 2]], quad[[0, 2, 3]]])  # covers the mirror's whole area
    mirror = np.array([quad[[1, 2, 3]], quad[[1, 3, 0]]])  # the same square, split the other way
    parts = [mirror, wall] if mirror_first else [wall, mirror]
    corners = np.concatenate(parts).astype(np.float32)
    is_mirror = np.array([1, 1, 0, 0] if mirror_first else [0, 0, 1, 1], np.uint8)
    got = rasterize(corners, is_mirror * FLAG_MIRROR, clip_from_world(cam), cam.width,
                    cam.height)
    covered = got.triangle >= 0
    assert covered.sum() > 500
    assert np.all(is_mirror[got.triangle[covered]] == 1)
    # the depth buffer holds the true eye-space depth, not the tie-breaking key
    np.testing.assert_allclose(got.depth[covered], reference(
        corners[is_mirror == 0], np.zeros(2, np.uint8), clip_from_world(cam), cam.width,
        cam.height)[3][covered], rtol=1e-6)
    # a bool array works as the mirror flag too
    got_bool = rasterize(corners, is_mirror.astype(bool), clip_from_world(cam), cam.width,
                         cam.height)
    assert got_bool.triangle.tobytes() == got.triangle.tobytes()


def _awkward_triangles(rng, n, guard):
    """Screen triangles of every kind the fill must survive: both windings, slivers,
    nearly horizontal and vertical edges, corners on pixel centres, far outside the image
    (to the guard band's edge)."""
    out = []
    for k in range(n):
        p = rng.uniform(-20, 90, (3, 2))
        kind = k % 6
        if kind == 1:
            p[1, 1] = p[0, 1] + rng.choice([1e-7, 1e-5, 1e-3, -1e-7])  # near-horizontal edge
        elif kind == 2:
            p[2] = p[0] + (p[1] - p[0]) * rng.uniform(0.2, 0.8) + rng.uniform(-0.05, 0.05, 2)
        elif kind == 3:
            p = np.floor(p) + 0.5  # corners and edges through pixel centres
        elif kind == 4:
            p[0] = rng.uniform(-guard, guard, 2)  # a far corner
        elif kind == 5:
            p[1, 0] = p[0, 0] + rng.choice([1e-9, 0.0, 1e-4])  # near-vertical edge
        out.append(p)
    return out


def _small_triangles(rng, n, w, h):
    """Triangles whose corners' box holds at most a few pixel centers (drawn by `_quad`
    when at most 2 x 2), all over the image and past its edges, some with corners and edges
    through pixel centers."""
    out = []
    for k in range(n):
        p = rng.uniform([-2, -2], [w + 2, h + 2]) + rng.uniform(-1.3, 1.3, (3, 2))
        if k % 3 == 0:
            p = np.floor(p * 2) / 2  # corners on pixel centres and edges
        out.append(p)
    return out


@pytest.mark.parametrize("seed", range(3))
def test_fill_matches_the_exact_pixel_by_pixel_twin(seed):
    """_fill (bounding box, edge functions stepped along rows, 1/w as a plane) covers
    exactly the pixels the twin's exact integer test with the top-left rule covers, with
    the same keys to float32 rounding; stencil, floor, culling and the box honoured."""
    rng = np.random.default_rng(seed)
    h, w = 48, 64
    bits, guard = _subpixel_bits(w, h)
    scale = float(1 << bits)
    stencil = (rng.random((h, w)) < 0.9).astype(np.uint8)
    floor = np.where(rng.random((h, w)) < 0.1, 5.0, 0.0).astype(np.float32)
    top, bottom, col0, col1 = 2, h - 1, 1, w
    box = (bottom - top, col1 - col0)
    covered = small = 0
    triangles = _awkward_triangles(rng, 300, guard) + _small_triangles(rng, 300, w, h)
    for t, p in enumerate(triangles):
        q = np.floor(p * scale + 0.5).astype(np.int64)
        ws = rng.uniform(0.05, 1.0, 3)
        use = (bool(t % 3), bool(t % 5 == 0))
        args = (t, 1.0 if t % 4 else 1.0 / 0.999, t % 3, q[0, 0], q[0, 1], ws[0], q[1, 0],
                q[1, 1], ws[1], q[2, 0], q[2, 1], ws[2], bits, top, bottom, col0, col1,
                stencil, use[0], floor, use[1])
        bufs = [(np.full(box, -1, np.int32), np.zeros(box, np.float32)) for _ in range(2)]
        _fill(*args, *bufs[0])
        fill_fixed(*args, *bufs[1])
        np.testing.assert_array_equal(bufs[0][0], bufs[1][0])
        np.testing.assert_allclose(bufs[0][1], bufs[1][1], rtol=1e-6)
        # buffers with the row and columns to spare that _draw gives (rows walked in whole
        # blocks, boxes of at most 2 x 2 pixels drawn by _quad): the same pixels and keys,
        # the spare row and columns untouched
        wide = (box[0] + 1, box[1] + _BLOCK - 1)
        blocked = (np.full(wide, -1, np.int32), np.zeros(wide, np.float32))
        _fill(*args, *blocked)
        np.testing.assert_array_equal(blocked[0][:box[0], :box[1]], bufs[0][0])
        np.testing.assert_array_equal(blocked[1][:box[0], :box[1]].view(np.int32),
                                      bufs[0][1].view(np.int32))
        assert np.all(blocked[0][:, box[1]:] == -1) and np.all(blocked[1][:, box[1]:] == 0)
        assert np.all(blocked[0][box[0]:] == -1) and np.all(blocked[1][box[0]:] == 0)
        s = _setup(*(np.int64(v) if i % 3 < 2 else np.float64(v) for i, v in
                     enumerate(args[3:12])), np.float64(args[1]), args[2], bits, top, bottom,
                   col0, col1)
        small += bool(s[0] and s[2] <= 2 and s[4] <= s[3] + 1)
        covered += int((bufs[0][0] >= 0).sum())
    assert covered > 3000 and small > 25


def test_shared_edges_are_covered_once():
    """A fan of triangles around a centre, and their diagonals through pixel centres: every
    pixel center inside the fan's hull is covered by exactly one triangle (no cracks, no
    double hits), corners and edges on pixel centres included."""
    h, w = 40, 40
    bits, _ = _subpixel_bits(w, h)
    one = 1 << bits
    center = np.array([20.5, 20.5]) * one
    angles = np.linspace(0, 2 * np.pi, 13)[:-1]
    ring = np.stack([20.5 + 15 * np.cos(angles), 20.5 + 15 * np.sin(angles)], 1)
    ring = np.floor(ring) + 0.5  # corners on pixel centres
    count = np.zeros((h, w), int)
    for k in range(len(ring)):
        a, b = ring[k] * one, ring[(k + 1) % len(ring)] * one
        tri = np.full((h, w), -1, np.int32)
        key = np.zeros((h, w), np.float32)
        _fill(k, 1.0, 0, int(center[0]), int(center[1]), 1.0, int(a[0]), int(a[1]), 1.0,
              int(b[0]), int(b[1]), 1.0, bits, 0, h, 0, w, np.ones((1, 1), np.uint8), False,
              np.zeros((1, 1), np.float32), False, tri, key)
        count += tri >= 0
    assert count.max() == 1
    # every pixel center strictly inside the ring polygon is covered (once)
    py, px = np.mgrid[0:h, 0:w] + 0.5
    cross = [(b[0] - a[0]) * (py - a[1]) - (b[1] - a[1]) * (px - a[0])
             for a, b in zip(ring, np.roll(ring, -1, axis=0), strict=True)]
    inside = np.all(np.array(cross) > 0, axis=0) | np.all(np.array(cross) < 0, axis=0)
    assert inside.sum() > 400
    assert np.all(count[inside] == 1)


@pytest.mark.parametrize("masked", [False, True])
def test_skipping_chunks_by_their_boxes_changes_nothing(masked):
    """With a workspace, runs of triangles whose world box misses the view (or the mask's
    box, or an extra plane's side) are skipped: the buffers are byte-identical to drawing
    every triangle, and some runs were in fact skipped."""
    from reflectcli.camera import standard_planes
    from reflectcli.raster.rasterize import RasterWorkspace
    from reflectcli.raster.rasterize.clip import _box_misses
    from reflectcli.raster.rasterize.constants import _CHUNK

    rng = np.random.default_rng(3)
    cam = camera(w=80, h=60)
    corners = random_triangles(cam, 8 * _CHUNK, rng, spread=3.0, size=(0.05, 0.3))
    # sorted along the screen's x so that runs of triangles are compact
    corners = corners[np.argsort(corners.mean(axis=1) @ cam.basis()[0])]
    m = clip_from_world(cam)
    right, _, back = cam.basis()
    extra = np.append(right, -right @ (cam.eye - 3 * back))  # keep world x-right of a point
    planes = np.vstack([standard_planes(), np.linalg.inv(m).T @ extra])  # clip space
    planes[2] /= np.abs(planes[2]).max()
    mask = np.zeros((60, 80), bool)
    if masked:
        mask[10:40, 45:70] = True
    else:
        mask[:] = True
    flags = np.zeros(len(corners), np.uint8)
    plain = rasterize(corners, flags, m, 80, 60, planes, mask=mask)
    ws = RasterWorkspace()
    fast = rasterize(corners, flags, m, 80, 60, planes, mask=mask, workspace=ws)
    # the same corners in one of the workspace's own buffers (drawn without run boxes)
    live_ws = RasterWorkspace()
    own = live_ws.get("virtual_corners", corners.shape, np.float32)
    own[:] = corners
    live = rasterize(own, flags, m, 80, 60, planes, mask=mask, workspace=live_ws)
    for name in ("triangle", "depth", "b1", "b2"):
        assert getattr(plain, name).tobytes() == getattr(fast, name).tobytes(), name
        assert getattr(plain, name).tobytes() == getattr(live, name).tobytes(), name
    assert (plain.triangle >= 0).sum() > 200
    bounds = ws.chunk_bounds(corners)
    all_planes = np.vstack([planes, np.ones((4, 4))])
    ys, xs = np.nonzero(mask)
    skipped = [_box_misses(bounds, c, m, all_planes, 3, 80, 60, xs.min(), xs.max() + 1,
                           ys.min(), ys.max() + 1) for c in range(len(bounds))]
    assert 0 < sum(skipped) < len(bounds)


def test_chunk_bounds_not_kept_for_the_workspace_own_buffers():
    """A scene's corners keep their run boxes across calls; corners in one of the
    workspace's own buffers (rewritten between calls, e.g. virtual's per-part corners) do
    not, so a rewritten buffer never meets stale boxes."""
    from reflectcli.raster.rasterize import RasterWorkspace

    ws = RasterWorkspace()
    scene_corners = np.ones((300, 3, 3), np.float32)
    assert ws.chunk_bounds(scene_corners) is ws.chunk_bounds(scene_corners)
    own = ws.get("virtual_corners", (300, 3, 3), np.float32)
    own[:] = 1.0
    first = ws.chunk_bounds(own).copy()
    own[:] = 5.0
    again = ws.chunk_bounds(own)  # the same view, rewritten
    assert (first == 1.0).all() and (again == 5.0).all()


def test_guarded_planes_are_made_once_per_arguments():
    """guarded_planes, kept by its arguments' values, gives each call an array of its own
    holding the planes and the guard band for that size."""
    from reflectcli.camera import standard_planes
    from reflectcli.raster.rasterize.fixed import _subpixel_bits, guarded_planes

    planes = standard_planes()
    for width, height in ((64, 48), (640, 480), (64, 48), (5000, 7)):
        got, bits = guarded_planes(planes, width, height)
        want_bits, guard = _subpixel_bits(width, height)
        gx, gy = 1.0 + 2.0 * guard / width, 1.0 + 2.0 * guard / height
        assert bits == want_bits and got.flags.c_contiguous
        assert got.tobytes() == np.vstack([planes, [[1.0, 0, 0, gx], [-1.0, 0, 0, gx],
                                                    [0, 1.0, 0, gy], [0, -1.0, 0, gy]]]).tobytes()
        got[:] = 0.0  # the caller's own
    other = np.vstack([planes, [[0.0, 0.0, 1.0, 0.5]]])
    assert guarded_planes(other, 64, 48)[0].shape == (len(other) + 4, 4)
    # made once per arguments: asked again, the kept pair is what is copied out
    from reflectcli.raster.rasterize import fixed

    fixed._GUARDED.clear()
    guarded_planes(planes, 64, 48)
    kept = next(iter(fixed._GUARDED.values()))
    guarded_planes(planes.copy(), 64, 48)
    assert len(fixed._GUARDED) == 1 and next(iter(fixed._GUARDED.values())) is kept


def test_zeroed_is_cleared_unless_given_back_zeroed():
    """RasterWorkspace.zeroed holds zeros: when made and grown, and after a user that did
    not say it left them (an interrupted frame); one that did is trusted, not cleared
    again (what saves the whole-array clear: a marker left there shows it was not)."""
    from reflectcli.raster.rasterize import RasterWorkspace

    ws = RasterWorkspace()
    a = ws.zeroed("marks", (4, 5), np.bool_)
    assert a.shape == (4, 5) and not a.any()
    a[1, 2] = True  # not given back: cleared on the next call
    assert not ws.zeroed("marks", (4, 5), np.bool_).any()
    b = ws.zeroed("marks", (4, 5), np.bool_)
    b[3, 3] = True
    ws.given_back_zeroed("marks")  # (a lie, to see that it is believed once)
    assert ws.zeroed("marks", (4, 5), np.bool_)[3, 3]
    assert not ws.zeroed("marks", (4, 5), np.bool_).any()  # the flag was used up
    c = ws.zeroed("marks", (2, 5), np.bool_)  # smaller: a view of the same zeros
    c[0, 0] = True
    ws.given_back_zeroed("marks")
    grown = ws.zeroed("marks", (40, 50), np.bool_)  # grown: made anew
    assert grown.shape == (40, 50) and not grown.any()


def test_claim_hands_out_each_piece_once():
    """parallel.claim against its twin: on one thread the same sequence; over two threads
    every piece is claimed exactly once (each worker records what it claimed)."""
    from naive import claim as naive_claim
    from numba import njit, prange

    from reflectcli.parallel import claim

    @njit(parallel=True)
    def claims(pieces, workers, out, counter):
        for w in prange(workers):
            while True:
                k = claim(counter)
                if k >= pieces:
                    break
                s = 0.0
                for i in range(2000):  # some work, so both workers take part
                    s += i * 1e-9
                out[k] += w + 1 + (s < -1.0)

    out, counter = np.zeros(1000, np.int64), np.zeros(1, np.int64)
    claims(1000, 2, out, counter)
    # one failed claim per worker past the end; no piece done twice (that would be 3)
    assert counter[0] == 1002 and np.isin(out, (1, 2)).all()
    fast, slow = np.zeros(1, np.int64), np.zeros(1, np.int64)

    @njit
    def three(counter):
        return claim(counter), claim(counter), claim(counter)

    assert three(fast) == tuple(naive_claim(slow) for _ in range(3))


@pytest.mark.parametrize("h", [1, 3, 4, 5, 480])
def test_claim_rows_hands_out_each_row_once(h):
    """parallel.claim_rows: bands of ROWS_PER_CLAIM rows, the last one cut at h, then empty
    bands; over two threads every row is handed out exactly once."""
    from numba import njit, prange

    from reflectcli.parallel import ROWS_PER_CLAIM, claim_rows

    @njit(parallel=True)
    def rows(h, workers, out, counter):
        for w in prange(workers):
            y0, y1 = claim_rows(counter, h)
            while y0 < y1:
                for y in range(y0, y1):
                    out[y] += w + 1
                y0, y1 = claim_rows(counter, h)

    out, counter = np.zeros(h, np.int64), np.zeros(1, np.int64)
    rows(h, 2, out, counter)
    assert np.isin(out, (1, 2)).all()

    @njit
    def bands(h, counter):
        found = []
        y0, y1 = claim_rows(counter, h)
        while y0 < y1:
            found.append((y0, y1))
            y0, y1 = claim_rows(counter, h)
        return found

    from naive import claim_rows as naive_claim_rows

    slow = np.zeros(1, np.int64)
    want = [naive_claim_rows(slow, h, ROWS_PER_CLAIM) for _ in range(-(-h // ROWS_PER_CLAIM))]
    assert bands(h, np.zeros(1, np.int64)) == want
    assert naive_claim_rows(slow, h, ROWS_PER_CLAIM)[0] == h  # then empty


def test_stencil_box_matches_twin():
    """The masked pass's box against numpy's any along each axis: empty, one pixel at each
    corner, full, thin lines, random sparse stencils and widths not a multiple of 8."""
    from reflectcli.raster.rasterize.stencil import stencil_box

    rng = np.random.default_rng(11)
    cases = [np.zeros((7, 13), np.uint8), np.ones((5, 9), np.uint8)]
    for y, x in ((0, 0), (0, 12), (6, 0), (6, 12), (3, 5)):
        s = np.zeros((7, 13), np.uint8)
        s[y, x] = 1
        cases.append(s)
    line = np.zeros((40, 33), np.uint8)
    line[:, 17] = 1
    cases.append(line)
    cases += [(rng.random((rng.integers(1, 60), rng.integers(1, 70))) < p).astype(np.uint8)
              for p in (0.001, 0.01, 0.2) for _ in range(20)]
    for s in cases:
        assert stencil_box(s) == naive_stencil_box(s), s.shape


@pytest.mark.parametrize("threads", [1, 2])
def test_clear_outside_false_keeps_pixels_outside_the_box(threads):
    """A masked pass with clear_outside=False into a workspace's outputs: inside the
    stencil's box the very bytes of a cleared pass; outside it, what the last call left
    (virtual's passes read only their box); an empty drawing still clears its box."""
    from reflectcli.raster.rasterize import RasterWorkspace

    rng = np.random.default_rng(5)
    cam = camera(w=80, h=60)
    corners = random_triangles(cam, 400, rng, spread=3.0, size=(0.05, 0.3))
    m = clip_from_world(cam)
    flags = np.zeros(len(corners), np.uint8)
    mask = np.zeros((60, 80), bool)
    mask[12:37, 20:61] = True
    mask[12, 20] = mask[30, 50] = False  # the box, not the whole rectangle
    before = numba.get_num_threads()
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    try:
        want = rasterize(corners, flags, m, 80, 60, mask=mask)
        ws = RasterWorkspace(outputs=True)
        rasterize(corners, flags, m, 80, 60, workspace=ws)  # the whole image drawn first
        old_tri = ws.get("tri", (60, 80), np.int32).copy()
        old_depth = ws.get("depth", (60, 80), np.float32).copy()
        got = rasterize(corners, flags, m, 80, 60, mask=mask, workspace=ws,
                        clear_outside=False)
        inside = np.zeros((60, 80), bool)
        inside[12:37, 20:61] = True
        assert (got.triangle[inside] == want.triangle[inside]).all()
        assert got.depth[inside].tobytes() == want.depth[inside].tobytes()
        assert (got.triangle[~inside] == old_tri[~inside]).all()
        assert got.depth[~inside].tobytes() == old_depth[~inside].tobytes()
        assert (old_tri[~inside] >= 0).sum() > 50 and (want.triangle[inside] >= 0).sum() > 50
        empty = rasterize(corners[:0], flags[:0], m, 80, 60, mask=mask, workspace=ws,
                          clear_outside=False)
        assert (empty.triangle[inside] == -1).all() and np.isinf(empty.depth[inside]).all()
        assert (empty.triangle[~inside] == old_tri[~inside]).all()
    finally:
        numba.set_num_threads(before)


def test_planes_past_near_and_far_classify_each_triangle():
    """`_run_setup`'s status against a third plane (x >= -0.5 in clip space): a triangle
    inside it is simple (drawn by the fast path), one it cuts is clipped, one outside it
    culled. (A slip made every triangle 'cut' whenever a third plane was given: the same
    pixels, all drawn through the slow clipped path.)"""
    from reflectcli.raster.rasterize.buffers import read_only
    from reflectcli.raster.rasterize.constants import _CHUNK, _CLIPPED, _CULLED, _SIMPLE
    from reflectcli.raster.rasterize.setup import _run_setup

    width = height = 64
    bits, guard = _subpixel_bits(width, height)
    g = 1.0 + 2.0 * guard / width
    planes = np.array([[0.0, 0, 1, 1], [0, 0, -1, 1], [1, 0, 0, 0.5],  # near, far, x >= -0.5
                       [1, 0, 0, g], [-1, 0, 0, g], [0, 1, 0, g], [0, -1, 0, g]])
    corners = np.array([[[0.0, 0, 0], [0.5, 0, 0], [0, 0.5, 0]],  # inside
                        [[-0.9, 0, 0], [0.5, 0, 0], [0, 0.5, 0]],  # cut
                        [[-0.9, 0, 0], [-0.6, 0, 0], [-0.9, 0.5, 0]]],  # outside
                       np.float32)
    ints = np.zeros(22 * _CHUNK, np.int64)
    floats = np.zeros(8 * _CHUNK)
    status = np.zeros(_CHUNK, np.uint8)
    # (read-only flags, as the draws hand them: no second signature of the kernel)
    kept = _run_setup(corners, read_only(np.zeros(3, np.uint8)), np.eye(4), planes, 3, width,
                      height, bits, float(1 << bits), 0, 0, height, 0, width, 0, 3, ints,
                      floats, status)
    assert list(status[:3]) == [_SIMPLE, _CLIPPED, _CULLED]
    assert kept == 1 and ints[21 * _CHUNK] == 0  # the inside one listed for drawing


@pytest.mark.parametrize("threads", [1, 2])
def test_flagged_back_faces_are_dropped_as_if_skipped(threads):
    """FLAG_CULL_BACK drops a triangle exactly when the eye is behind its plane (its world
    winding turned away: clockwise on screen), FLAG_CULL_FRONT exactly when the eye is in
    front of it, clipped or not, besides what the pass culls:
    the same buffers as FLAG_SKIP on those triangles. Triangles cross the near plane and leave
    the guard band (the clipped fans), of both windings, in runs set up in place and
    listed."""
    rng = np.random.default_rng(7)
    cam = camera(w=64, h=48, near=0.5)
    m = clip_from_world(cam)
    near_ones = random_triangles(cam, 300, rng, depth=(0.2, 3.0), spread=3.0, size=(1, 6))
    corners = np.concatenate([random_triangles(cam, 700, rng), near_ones])
    corners[::2] = corners[::2, ::-1]  # both windings
    flagged = rng.random(len(corners)) < 0.5
    p0, p1, p2 = (corners[:, k].astype(np.float64) for k in range(3))
    facing = np.einsum("ij,ij->i", np.cross(p1 - p0, p2 - p0), cam.eye - p0)
    assert (facing > 0).sum() > 300 and (facing < 0).sum() > 300
    flags = np.where(rng.random(len(corners)) < 0.2, FLAG_MIRROR, 0).astype(np.uint8)
    numba.set_num_threads(threads)
    try:
        # FLAG_CULL_FRONT: the faces turned toward the eye (a reflection pass's far faces)
        for flag, dropped in ((FLAG_CULL_BACK, facing < 0), (FLAG_CULL_FRONT, facing > 0)):
            for cull in (CULL_NONE, CULL_FRONT, CULL_BACK):
                got = rasterize(corners, flags | np.where(flagged, flag, 0).astype(np.uint8),
                                m, cam.width, cam.height, cull=cull)
                want = rasterize(corners, flags | np.where(flagged & dropped, FLAG_SKIP, 0)
                                 .astype(np.uint8), m, cam.width, cam.height, cull=cull)
                assert got.triangle.tobytes() == want.triangle.tobytes()
                assert got.depth.tobytes() == want.depth.tobytes()
                assert np.isin(got.triangle, np.flatnonzero(flagged & dropped)).sum() == 0
    finally:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
