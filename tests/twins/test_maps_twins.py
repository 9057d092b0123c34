"""Map kernels (cube and sphere lookups, the envmap lookup with box projection, dprm's
surface reconstruction, the warp's projection, adaptive radii and splat) against twins."""

from __future__ import annotations

import numpy as np
import pytest
from naive import (
    adaptive_radii,
    add_reflections,
    box_exit,
    cube_face_coords,
    cube_sample,
    image_sample,
    project,
    sphere_coords,
    sphere_from_cube,
    sphere_sample,
    splat_sequential,
    surface_intersect,
)

from reflectcli.camera import Camera
from reflectcli.geometry import reflection_matrix
from reflectcli.maps import cube, lookup, sphere, surface, warp
from reflectcli.scene.types import CYLINDER, MESH, PLANAR, SPHERE


def directions(rng, n=300):
    d = list(rng.normal(size=(n, 3)))
    # edge cases: the axes, ties between axes, face corners, the sphere map's rim
    for v in np.eye(3):
        d += [v, -v]
    d += [np.array([1.0, 1.0, 0.0]), np.array([-1.0, 0.0, 1.0]), np.array([0.0, 1.0, -1.0]),
          np.array([1.0, 1.0, 1.0]), np.array([-1.0, -1.0, -1.0]), np.array([0.0, 0.0, -1.0]),
          np.array([1e-9, 0.0, -1.0]), np.array([0.3, -0.2, 1.0])]
    return d


@pytest.mark.parametrize("bilinear", [False, True])
@pytest.mark.parametrize("res", [1, 2, 5])
def test_image_sample_matches_twin(res, bilinear):
    rng = np.random.default_rng(res)
    image = rng.random((res, res, 3)).astype(np.float32)
    uv = list(rng.uniform(-0.1, 1.1, (80, 2))) + [(0.0, 0.0), (1.0, 1.0), (0.5, 0.5),
                                                  (1.0 / res, 0.0), (0.999999, 0.0)]
    for u, v in uv:
        np.testing.assert_allclose(cube.image_sample(image, u, v, bilinear),
                                   image_sample(image, u, v, bilinear), rtol=1e-6, atol=1e-7)


def _filled_array(image, u, v, bilinear):
    """image_sample as it was before it returned a tuple: the float64 sums of the kernel,
    in its order, stored into a float32 array of 3."""
    res = image.shape[0]
    img = image.astype(np.float64)
    fx, fy = u * res, v * res
    if not bilinear or res == 1:
        x, y = min(max(int(fx), 0), res - 1), min(max(int(fy), 0), res - 1)
        return img[y, x].astype(np.float32)
    fx, fy = min(max(fx - 0.5, 0.0), res - 1.0), min(max(fy - 0.5, 0.0), res - 1.0)
    x0, y0 = min(int(fx), res - 2), min(int(fy), res - 2)
    ax, ay = fx - x0, fy - y0
    return np.array([(1 - ax) * (1 - ay) * img[y0, x0, c] + ax * (1 - ay) * img[y0, x0 + 1, c]
                     + (1 - ax) * ay * img[y0 + 1, x0, c] + ax * ay * img[y0 + 1, x0 + 1, c]
                     for c in range(3)], np.float32)


@pytest.mark.parametrize("bilinear", [False, True])
@pytest.mark.parametrize("res", [1, 2, 5])
def test_image_sample_tuple_has_the_arrays_bits(res, bilinear):
    """The (r, g, b) tuple holds the bits the float32 array it replaced held (rounded once
    from the float64 sum): the speed change kept every map lookup's bytes. The twin test
    above allows 1e-6, which a float64 result or a second rounding would pass."""
    rng = np.random.default_rng(10 + res)
    image = rng.random((res, res, 3)).astype(np.float32)
    for u, v in list(rng.uniform(-0.1, 1.1, (200, 2))) + [(0.0, 0.0), (1.0, 1.0)]:
        got = cube.image_sample(image, u, v, bilinear)
        assert all(float(np.float32(c)) == c for c in got)  # float32 values
        np.testing.assert_array_equal(np.array(got, np.float32),
                                      _filled_array(image, u, v, bilinear))


@pytest.mark.parametrize("bilinear", [False, True])
def test_cube_lookup_matches_twin(bilinear):
    rng = np.random.default_rng(1)
    faces = rng.random((6, 4, 4, 3)).astype(np.float32)
    bases = cube.face_bases()
    for r in directions(rng):
        face, u, v = cube.cube_face_coords(bases, *r)
        want = cube_face_coords(r)
        assert face == want[0], r
        np.testing.assert_allclose((u, v), want[1:], atol=1e-12)
        np.testing.assert_allclose(cube.cube_sample(faces, bases, *r, bilinear),
                                   cube_sample(faces, r, bilinear), rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("bilinear", [False, True])
def test_sphere_lookup_matches_twin(bilinear):
    rng = np.random.default_rng(2)
    image = rng.random((6, 6, 3)).astype(np.float32)
    for r in directions(rng):
        np.testing.assert_allclose(sphere.sphere_coords(*r), sphere_coords(r), atol=1e-12)
        np.testing.assert_allclose(sphere.sphere_sample(image, *r, bilinear),
                                   sphere_sample(image, r, bilinear), rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("res", [1, 5, 8])
def test_sphere_from_cube_matches_twin(res):
    faces = np.random.default_rng(res).random((6, 4, 4, 3)).astype(np.float32)
    np.testing.assert_allclose(sphere.sphere_from_cube(faces, res), sphere_from_cube(faces, res),
                               rtol=1e-5, atol=1e-6)


def test_box_exit_matches_twin():
    rng = np.random.default_rng(3)
    lo, hi = np.array([-1.0, 0.0, -2.0]), np.array([2.0, 3.0, 1.0])
    cases = [(rng.uniform(lo - 0.3, hi + 0.3), rng.normal(size=3)) for _ in range(300)]
    # edge cases: on a face (a mirror on the wall), on a corner, just outside within the
    # tolerance, axis-aligned directions, a zero component, pointing into the face it sits on
    cases += [(np.array([-1.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0])),
              (np.array([-1.0, 1.0, 0.0]), np.array([-1.0, 0.2, 0.0])),
              (hi.copy(), np.array([-1.0, -1.0, -1.0])),
              (np.array([2.0002, 1.0, 0.0]), np.array([-1.0, 0.0, 0.0])),
              (np.array([2.01, 1.0, 0.0]), np.array([-1.0, 0.0, 0.0])),
              (np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])),
              (np.array([0.0, 1.0, 0.0]), np.array([0.0, -2.0, 0.0]))]
    for p, r in cases:
        got = lookup.box_exit(*p, *r, lo, hi)
        want = box_exit(p, r, lo, hi)
        if want < 0:
            assert got == -1.0
        else:
            np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)


def mirror_case(kind, rng):
    """(params, corners (T, 3, 3) on the mirror, normals) of a small reflector."""
    params = np.zeros(16)
    u = rng.uniform(0, 1, (6, 3, 2))
    if kind == PLANAR:
        n = np.array([0.1, 0.2, 1.0])
        n /= np.linalg.norm(n)
        params[:4] = (*n, -0.1)
        e1 = np.cross(n, [0.0, 1.0, 0.0])
        e2 = np.cross(n, e1)
        pts = -0.1 * n + u[..., :1] * e1 + u[..., 1:] * e2
    elif kind == SPHERE:
        params[:4] = (0.2, 0.5, -0.3, 0.8)
        d = rng.normal(size=(6, 3, 3)) + np.array([0.0, 0.0, 2.0])
        pts = params[:3] + 0.8 * d / np.linalg.norm(d, axis=2, keepdims=True)
    elif kind == CYLINDER:
        params[:8] = (0.0, -0.5, 0.0, 0.0, 1.0, 0.0, 0.6, 1.5)
        ang = rng.uniform(-1, 1, (6, 3))
        pts = np.stack([0.6 * np.sin(ang), rng.uniform(-0.5, 1.0, (6, 3)), 0.6 * np.cos(ang)], 2)
    else:
        pts = rng.uniform(-1, 1, (6, 3, 3)) * np.array([1, 1, 0.2])
    normals = rng.normal(size=(6, 3, 3)) * 0.2 + np.array([0.0, 0.0, 1.0])
    return params, pts.astype(np.float32), normals.astype(np.float32)


@pytest.mark.parametrize("map_kind", [lookup.CUBE, lookup.SPHERE_MAP])
@pytest.mark.parametrize("kind", [PLANAR, SPHERE, CYLINDER, MESH])
def test_envmap_lookup_matches_twin(kind, map_kind):
    rng = np.random.default_rng(kind * 7 + map_kind)
    h, w = 6, 7
    params, corners, normals = mirror_case(kind, rng)
    tri = rng.integers(0, 6, (h, w)).astype(np.int32)
    b = rng.dirichlet([1, 1, 1], (h, w)).astype(np.float32)
    surface_ids = np.where(rng.random((h, w)) < 0.8, 4, 2).astype(np.int32)
    faces = rng.random((6, 5, 5, 3)).astype(np.float32)
    sph = rng.random((7, 7, 3)).astype(np.float32)
    refl = np.array([0.9, 0.5, 0.2], np.float32)
    eye = np.array([0.3, 0.8, 4.0])
    lo, hi = np.array([-3.0, -1.0, -3.0]), np.array([3.0, 3.0, 5.0])
    capture = np.array([0.1, 0.4, 0.2])
    for parallax in (False, True):
        for bilinear in (False, True):
            rgb = rng.random((h, w, 3)).astype(np.float32)
            got = rgb.copy()
            lookup._add(got, tri, b[..., 1].copy(), b[..., 2].copy(), surface_ids, 4, corners,
                        normals, kind, params, refl, eye, capture, lo, hi, parallax, map_kind,
                        faces, sph, cube.face_bases(), bilinear, 2)
            want = add_reflections(rgb, tri, b[..., 1], b[..., 2], surface_ids, 4, corners,
                                   normals, kind, params, refl, eye, capture, lo, hi, parallax,
                                   map_kind, faces, sph, bilinear)
            # a direction on a texel or face boundary may round either way: the rest agree
            close = np.abs(got - want).max(axis=2) <= 1e-5
            assert close.mean() >= 0.97, (parallax, bilinear)
            assert np.all(got[surface_ids != 4] == rgb[surface_ids != 4])


@pytest.mark.parametrize("seed", range(3))
def test_surface_reconstruction_matches_twin(seed):
    rng = np.random.default_rng(seed)
    cam = Camera(np.array([0.2, 1.0, 3.0]), np.array([0.0, 0.8, -1.0]), np.array([0, 1.0, 0]),
                 50.0, 9, 7, 0.1, 50.0)
    n = np.array([0.0, 0.1, 1.0])
    n /= np.linalg.norm(n)
    d = 0.5  # the mirror plane n.x + d = 0, the eye in front of it
    refl = reflection_matrix(n, d)
    mirrored_eye = (refl @ np.append(cam.eye, 1.0))[:3]
    corners = rng.uniform(-3, 3, (10, 3, 3)).astype(np.float32)
    corners[0] = [[0, 0, 1], [1, 0, 1], [0, 1, 1]]  # a triangle parallel to... the image plane
    corners[1] = [[0, 0, 0], [1, 0, 0], [2, 0, 0]]  # degenerate: never hit
    triangle = rng.integers(-1, 10, (7, 9)).astype(np.int32)
    got = [triangle.copy(), np.zeros((7, 9), np.float32), np.zeros((7, 9), np.float32),
           np.full((7, 9), np.inf, np.float32)]
    right, up, back = cam.basis()
    t = np.tan(np.radians(cam.fov_y) / 2)
    r3 = refl[:3, :3]
    axes = np.stack([r3 @ (right * t * cam.aspect), r3 @ (up * t), r3 @ back])
    surface._intersect(triangle, axes, mirrored_eye, corners, n, d, *got)
    want = surface_intersect(triangle, cam, refl, mirrored_eye, corners, n, d)
    np.testing.assert_array_equal(got[0], want[0])
    hit = want[0] >= 0
    assert hit.sum() > 5 and (hit != (triangle >= 0)).any()
    np.testing.assert_allclose(got[1][hit], want[1][hit], rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(got[2][hit], want[2][hit], rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(got[3][hit], want[3][hit], rtol=1e-5)


def _map_beside_camera(rng, mh, mw, width, height, near):
    """A random (mh, mw) depth map (some empty, NaN, zero and negative zexels), a screen
    camera, and the map's camera beside it, wider and turned: some zexels land off screen,
    some behind."""
    depth = rng.uniform(0.5, 6.0, (mh, mw)).astype(np.float32)
    depth[rng.random((mh, mw)) < 0.1] = np.inf
    depth[0, :3] = (np.nan, 0.0, -1.0)
    cam = Camera(np.array([0.0, 1.0, 3.0]), np.array([0.0, 1.0, 0.0]), np.array([0, 1.0, 0]),
                 50.0, width, height, near, 50.0)
    map_cam = Camera(np.array([1.5, 1.2, 2.5]), rng.uniform(-2, 2, 3) + [0.0, 1.0, 0.0],
                     np.array([0, 1.0, 0]), 100.0, mw, mh, 0.1, 50.0)
    return depth, cam, map_cam


@pytest.mark.parametrize("seed", range(3))
def test_warp_projection_matches_twin(seed):
    rng = np.random.default_rng(seed)
    mh, mw, width, height, near = 9, 11, 20, 16, 0.2
    depth, cam, map_cam = _map_beside_camera(rng, mh, mw, width, height, near)
    w = warp.warp_matrix(map_cam, cam, np.eye(4))
    for box in ((0, width, 0, height), (4, 12, 3, 10)):
        got = warp.project_map(depth, w, width, height, near, box, margin=2)
        x0, x1, y0, y1 = box
        want = project(depth, w, near, (x0 - 2, x1 + 2, y0 - 2, y1 + 2), width, height)
        np.testing.assert_array_equal(np.isnan(got[0]), np.isnan(want[0]))
        ok = ~np.isnan(want[0])
        assert ok.sum() > 10
        np.testing.assert_allclose(got[0][ok], want[0][ok], rtol=1e-5, atol=1e-4)
        np.testing.assert_allclose(got[1][ok], want[1][ok], rtol=1e-5, atol=1e-4)
        np.testing.assert_allclose(got[2][ok], want[2][ok], rtol=1e-5)
        # rows: the floor of the float32 screen y the kernel returns; the twin's (from
        # float64) may differ only for a zexel within 1e-4 px of a row boundary
        rows = np.floor(got[1]).reshape(mh, mw)
        okr = ok.reshape(mh, mw)
        np.testing.assert_array_equal(got[3], np.where(okr, rows, 1 << 40).min(axis=1))
        hi = np.where(okr, rows, -np.inf).max(axis=1)
        np.testing.assert_array_equal(got[4], np.where(okr.any(axis=1), hi, -1))
        y64 = want[1][ok]
        near_edge = np.abs(y64 - np.round(y64)) < 1e-4
        same = np.floor(got[1][ok]) == np.floor(np.float32(y64))
        assert (same | near_edge).all()


@pytest.mark.parametrize("seed", range(3))
def test_adaptive_radii_match_twin(seed):
    rng = np.random.default_rng(seed)
    mh, mw = 10, 12
    v, u = np.mgrid[0:mh, 0:mw]
    step = rng.uniform(0.3, 9.0)
    sx = (u * step + rng.normal(0, 0.3, (mh, mw))).reshape(-1).astype(np.float32)
    sy = (v * step * rng.uniform(0.5, 1.5) + rng.normal(0, 0.3, (mh, mw))).reshape(-1).astype(
        np.float32)
    z = np.where(rng.random(mh * mw) < 0.7, 2.0, 2.08).astype(np.float32)  # two surfaces
    z[rng.random(mh * mw) < 0.05] = np.inf
    sx[rng.random(mh * mw) < 0.1] = np.nan
    radii = warp.splat_radii(sx, sy, z, (mh, mw), "adaptive")
    np.testing.assert_array_equal(radii, adaptive_radii(sx, sy, z, mh, mw))
    for mode, r in (("1", 0), ("3", 1), ("5", 2)):
        assert np.all(warp.splat_radii(sx, sy, z, (mh, mw), mode) == r)


@pytest.mark.parametrize("ordered", [False, True])
@pytest.mark.parametrize("seed", range(3))
def test_splat_both_modes_match_sequential_twin(seed, ordered):
    """Several maps into one buffer, in ordered (McMillan) or z-buffer mode, with radii 0..2,
    zexels at infinity and exact depth ties: the banded kernel equals one plain pass."""
    rng = np.random.default_rng(seed)
    h, w = 14, 17
    stencil = rng.random((h, w)) < 0.85
    best_zd = np.full((h, w, 2), np.inf, np.float32)
    best_id = np.full((h, w), -1, np.int64)
    maps = []
    sizes = [(6, 7), (5, 9)]
    stride = max(a * b for a, b in sizes)
    for slot, (mh, mw) in enumerate(sizes):
        n = mh * mw
        sx = rng.uniform(-0.5, w + 0.5, n).astype(np.float32)
        sy = rng.uniform(0, h - 1e-3, n).astype(np.float32)
        sx[rng.random(n) < 0.1] = np.nan
        z = rng.choice([1.0, 1.005, 3.0, np.inf], n).astype(np.float32)
        radii = rng.integers(0, 3, n).astype(np.int8)
        runs = (warp.ordered_runs(mh, mw, rng.uniform(0, mw), rng.uniform(0, mh),
                                  bool(rng.random() < 0.5)) if ordered
                else warp.raster_runs(mh, mw))
        rows = np.floor(sy).reshape(mh, mw)
        with np.errstate(invalid="ignore"):
            row_lo = np.where(np.isnan(sx.reshape(mh, mw)), 1 << 40, rows).min(axis=1)
            row_hi = np.where(np.isnan(sx.reshape(mh, mw)), -1, rows).max(axis=1)
        warp.splat(sx, sy, z, radii, runs, mw, row_lo.astype(np.int64),
                   row_hi.astype(np.int64), slot, stride, stencil, best_zd, best_id, ordered,
                   bands=3)
        maps.append((sx, sy, z, radii, runs, mw))
    want_z, want_id = splat_sequential(maps, stencil, ordered)
    np.testing.assert_array_equal(best_id, want_id)
    np.testing.assert_array_equal(best_zd[..., 0], want_z)
    assert (best_id >= 0).mean() > 0.5


@pytest.mark.parametrize("ordered", [False, True])
@pytest.mark.parametrize("seed", range(3))
def test_pixel_splat_both_modes_match_sequential_twin(seed, ordered):
    """The one-pixel splat of warp_depths' fast path: several maps into one buffer, in
    ordered (McMillan) or z-buffer mode, zexels at infinity and exact depth ties, a region
    inside the screen: the banded kernel equals one plain pass of the rule."""
    from conftest import projection_of

    rng = np.random.default_rng(seed)
    h, w = 14, 17
    stencil = rng.random((h, w)) < 0.85
    buffers = warp.WarpBuffers(h, w)
    buffers.best_id[:] = 7  # stale values: the region is cleared by the kernel
    region = (2, 15, 1, 12)
    x0, x1, y0, y1 = region
    maps = []
    sizes = [(6, 7), (5, 9)]
    stride = max(a * b for a, b in sizes)
    for slot, (mh, mw) in enumerate(sizes):
        n = mh * mw
        sx = rng.uniform(x0, x1 - 1e-3, n).astype(np.float32)
        sy = rng.uniform(y0, y1 - 1e-3, n).astype(np.float32)
        sx[rng.random(n) < 0.1] = np.nan
        z = rng.choice([1.0, 1.005, 3.0, np.inf], n).astype(np.float32)
        runs = (warp.ordered_runs(mh, mw, rng.uniform(0, mw), rng.uniform(0, mh),
                                  bool(rng.random() < 0.5)) if ordered
                else warp.raster_runs(mh, mw))
        proj = projection_of(sx, sy, z, mh, mw, (h, w))
        warp.splat_pixels(proj, runs, mw, slot * stride, stencil, buffers.best_zd,
                          buffers.best_id, ordered, region, slot == 0, True, bands=3)
        maps.append((sx, sy, z, np.zeros(n, np.int8), runs, mw))
    want_z, want_id = splat_sequential(maps, stencil, ordered)
    got_id = buffers.best_id[y0:y1, x0:x1]
    np.testing.assert_array_equal(got_id, want_id[y0:y1, x0:x1])
    np.testing.assert_array_equal(buffers.best_zd[y0:y1, x0:x1, 0], want_z[y0:y1, x0:x1])
    assert (got_id >= 0).mean() > 0.25  # one zexel a pixel: sparser than the wide splats


@pytest.mark.parametrize("ordered", [False, True])
@pytest.mark.parametrize("seed", range(3))
def test_splat_projecting_inside_matches_project_then_splat(seed, ordered):
    """warp_depths' one-pixel splat projects the map itself (row by row, per band): its
    result (ids, depths, distances, payload rows, the count of zexels landed in the region)
    equals `project_map` followed by the splat reading that projection, which the tests
    above hold to their twins. Projecting inside, the kernel bounds each map row's screen
    rows from its depths instead of projecting it twice, so its row spans need only contain
    the projection's (`test_row_reach_bounds_the_twin_projection` holds them to the twin)."""
    rng = np.random.default_rng(seed + 40)
    mh, mw, width, height, near = 30, 37, 20, 16, 0.2
    depth, cam, map_cam = _map_beside_camera(rng, mh, mw, width, height, near)
    wm = warp.warp_matrix(map_cam, cam, np.eye(4))
    stencil = rng.random((height, width)) < 0.85
    payload = rng.random((mh * mw, 3)).astype(np.float32)
    runs = (warp.ordered_runs(mh, mw, rng.uniform(0, mw), rng.uniform(0, mh), True)
            if ordered else warp.raster_runs(mh, mw))
    for box, radius in (((0, width, 0, height), 0), ((4, 12, 3, 10), 1)):
        x0, x1, y0, y1 = box
        grown = (x0 - radius, x1 + radius, y0 - radius, y1 + radius)
        region = (max(grown[0], 0), min(grown[1], width), max(grown[2], 0),
                  min(grown[3], height))
        results = []
        for inside in (False, True):
            buffers = warp.WarpBuffers(height, width)
            out = np.zeros((height, width, 3), np.float32)
            proj = warp.Projection.empty(mh, mw)
            if not inside:
                warp.project_map(depth, wm, width, height, near, box, radius, proj,
                                 positions=False)
                exact = proj.row_lo.copy(), proj.row_hi.copy(), proj.count.copy()
                rx, ry = proj.pix % width, proj.pix // width
                in_region = ((proj.pix >= 0) & (rx >= region[0]) & (rx < region[1])
                             & (ry >= region[2]) & (ry < region[3]))
            landed = warp.splat_pixels(proj, runs, mw, 0, stencil, buffers.best_zd,
                                       buffers.best_id, ordered, region, True, True, 3,
                                       payload, out,
                                       source=(depth, wm, near, grown) if inside else None)
            results.append((buffers.best_zd.copy(), buffers.best_id.copy(), out, landed))
        for a, b in zip(*results, strict=True):
            np.testing.assert_array_equal(a, b)
        assert results[1][3] == in_region.sum()
        warped = exact[2] > 0
        assert warped.sum() > 5
        assert (proj.row_lo[warped] <= exact[0][warped]).all()
        assert (proj.row_hi[warped] >= exact[1][warped]).all()
        assert (results[0][1] >= 0).sum() > 20


@pytest.mark.parametrize("wide", [False, True])
@pytest.mark.parametrize("seed", range(4))
def test_row_reach_bounds_the_twin_projection(seed, wide):
    """The one-pixel splat skips, per band, the map rows that cannot reach it by bounds on
    each row's screen rows taken from its depths' range alone (`_row_reach`): every row a
    zexel of the map row lands in (by the twin's projection, and by the kernel's float32
    one) lies within them. Narrow depth ranges give tight bounds; `wide`: depths span 1e-3
    to 1e4 with infinite, subnormal, zero, negative and NaN ones, and wide, turned map
    cameras put rows across the eye plane (their bounds are every row)."""
    rng = np.random.default_rng(seed + 70)
    mh, mw, width, height, near = 24, 29, 40, 30, 0.05
    if wide:
        depth = np.exp(rng.uniform(np.log(1e-3), np.log(1e4), (mh, mw))).astype(np.float32)
        depth[rng.random((mh, mw)) < 0.1] = np.inf
        depth[rng.random((mh, mw)) < 0.05] = rng.choice([np.nan, 0.0, -1.0, 1e-40])
        depth[3] = np.inf  # a row of directions only
    else:
        depth = rng.uniform(1.0, 3.0, (mh, mw)).astype(np.float32)
        depth[5, ::4] = np.inf
        depth[6, ::3] = np.nan
    depth[4] = rng.uniform(2.0, 2.1, mw)  # a narrow depth range
    cam = Camera(np.array([0.0, 1.0, 3.0]), np.array([0.0, 1.0, 0.0]), np.array([0, 1.0, 0]),
                 60.0, width, height, near, 50.0)
    if wide:
        map_cam = Camera(rng.uniform(-2, 2, 3) + [0.0, 1.0, 3.0], rng.uniform(-3, 3, 3),
                         np.array([0, 1.0, 0]), rng.uniform(60.0, 150.0), mw, mh, 0.1, 50.0)
    else:
        map_cam = Camera(rng.uniform(-0.3, 0.3, 3) + [0.0, 1.0, 3.0],
                         rng.uniform(-0.3, 0.3, 3) + [0.0, 1.0, 0.0], np.array([0, 1.0, 0]),
                         50.0, mw, mh, 0.1, 50.0)
    wm = warp.warp_matrix(map_cam, cam, np.eye(4))
    box = (0, width, 0, height)
    proj = warp.Projection.empty(mh, mw)
    buffers = warp.WarpBuffers(height, width)
    warp.splat_pixels(proj, warp.raster_runs(mh, mw), mw, 0, np.ones((height, width), bool),
                      buffers.best_zd, buffers.best_id, False, box, True, False, 3,
                      source=(depth, wm, near, box))
    lo, hi = proj.row_lo.copy(), proj.row_hi.copy()
    _, sy, _, _, _ = project(depth, wm, near, box, width, height)
    rows = np.floor(sy.reshape(mh, mw))
    kernel = warp.Projection.empty(mh, mw)
    warp.project_map(depth, wm, width, height, near, box, 0, kernel, positions=False)
    kernel_rows = np.where(kernel.pix >= 0, kernel.pix // width, -1).reshape(mh, mw)
    for v in range(mh):
        for row in list(rows[v][~np.isnan(rows[v])]) + list(kernel_rows[v][kernel_rows[v] >= 0]):
            assert lo[v] <= row <= hi[v], (v, row, lo[v], hi[v])
    assert (~np.isnan(rows)).sum() > 20
    if not wide:  # the bounds skip rows: most spans are well under the screen's height
        assert np.median(hi - lo) < height / 2
