"""Shading, primary rays, the raster shading pass and the rasterizer's mask, depth floor,
culling and skip flags against their slow twins in tests/naive.py."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import compiled_only
from naive import add_reflection as naive_add_reflection
from naive import (
    material_albedo,
    primary_rays,
    rasterize,
    shade,
    shade_stencil,
    surface_color,
)
from naive import run_bounds as naive_run_bounds

from reflectcli.camera import Camera
from reflectcli.raster.bounds import run_bounds
from reflectcli.raster.rasterize import (
    CULL_BACK,
    CULL_FRONT,
    CULL_NONE,
    FLAG_CULL_BACK,
    FLAG_CULL_FRONT,
    FLAG_MIRROR,
    FLAG_SKIP,
)
from reflectcli.raster.rasterize import (
    rasterize as fast_rasterize,
)
from reflectcli.raster.shade import _shade, _shade_stencil, add_reflection
from reflectcli.scene.types import CHECKER, DIRECTIONAL, LAMBERT, POINT, SOLID, TEXTURE, UNLIT
from reflectcli.shading import material_albedo as fast_albedo
from reflectcli.shading import surface_color as fast_surface_color
from reflectcli.trace.rays import primary_rays as fast_primary_rays


def materials(rng):
    """solid, checker, nearest and bilinear textures (4x3, 1x1, 5x1), and a checker with a
    non-integer scale: (mat_i, mat_f, texels)."""
    texels = [np.zeros((1, 3), np.float32)]
    mat_i, mat_f = [], []

    def texture(w, h, bilinear, scale):
        off = sum(len(t) for t in texels)
        texels.append(rng.random((w * h, 3)).astype(np.float32))
        mat_i.append([TEXTURE, off, w, h, bilinear])
        mat_f.append([0, 0, 0, 0, 0, 0, *scale])

    mat_i.append([SOLID, 0, 0, 0, 0])
    mat_f.append([*rng.random(3), 0, 0, 0, 1, 1])
    mat_i.append([CHECKER, 0, 0, 0, 0])
    mat_f.append([*rng.random(6), 4, 3])
    mat_i.append([CHECKER, 0, 0, 0, 0])
    mat_f.append([*rng.random(6), 2.5, 0.7])
    texture(4, 3, 0, (1, 1))
    texture(4, 3, 1, (2, 3))
    texture(1, 1, 1, (1, 1))
    texture(5, 1, 1, (1.5, 1))
    texture(3, 4, 0, (3, 2))
    return (np.array(mat_i, np.int32), np.array(mat_f, np.float32),
            np.ascontiguousarray(np.concatenate(texels)))


def uv_samples(rng, n=60):
    """Random uvs in and beyond [0, 1] (wrap), and the edge values: integers, texel and
    checker boundaries, texel centers, tiny negatives."""
    edges = [0.0, 1.0, -1.0, 0.5, 0.25, 1 / 3, 2 / 3, 0.125, 1e-12, -1e-12, 1 - 1e-12, 2.0,
             0.1, 0.2, 0.4]
    uv = [(a, b) for a in edges for b in edges[:6]]
    uv += [tuple(x) for x in rng.uniform(-2.5, 2.5, (n, 2))]
    return uv


@compiled_only
@pytest.mark.parametrize("seed", range(3))
def test_material_albedo_matches_twin(seed):
    rng = np.random.default_rng(seed)
    mat_i, mat_f, texels = materials(rng)
    for mat in range(len(mat_i)):
        for u, v in uv_samples(rng):
            got = fast_albedo(mat, u, v, mat_i, mat_f, texels)
            want = material_albedo(mat, u, v, mat_i, mat_f, texels)
            np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-7,
                                       err_msg=f"material {mat} at uv ({u}, {v})")


def lights(rng):
    """Two point lights (one close), a directional light, and one pointing sideways."""
    rows = [[POINT, *rng.uniform(-3, 3, 3), *rng.uniform(0, 5, 3)],
            [POINT, 0.3, 0.2, 0.1, *rng.uniform(0, 2, 3)]]
    for d in (rng.normal(size=3), np.array([1.0, 0.0, 0.0])):
        rows.append([DIRECTIONAL, *(d / np.linalg.norm(d)), *rng.uniform(0, 1, 3)])
    return np.array(rows, np.float32)


@pytest.mark.parametrize("shading", [UNLIT, LAMBERT])
@pytest.mark.parametrize("seed", range(3))
def test_surface_color_matches_twin(shading, seed):
    rng = np.random.default_rng(seed)
    mat_i, mat_f, texels = materials(rng)
    light_f = lights(rng)
    cases = []
    for _ in range(120):
        p = rng.uniform(-2, 2, 3)
        n = rng.normal(size=3) * rng.uniform(0.1, 3)  # not unit: the kernel normalises
        d = rng.normal(size=3)
        cases.append((p, n, d))
    # edge cases: a normal perpendicular to the view (no flip), facing away (flipped), a light
    # grazing the surface, a light behind it
    cases.append((np.zeros(3), np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0])))
    cases.append((np.zeros(3), np.array([0.0, 1.0, 0.0]), np.array([0.0, 1.0, 0.0])))
    cases.append((np.array([0.3, 0.2, -0.9]), np.array([1.0, 0.0, 0.0]),
                  np.array([0.0, 0.0, -1.0])))
    for ambient in (0.0, 0.15):
        for mat in range(len(mat_i)):
            for k, (p, n, d) in enumerate(cases[:: 1 + 5 * (mat > 0)]):
                u, v = rng.uniform(-1.5, 1.5, 2) if k % 3 else (0.5, 0.0)
                got = fast_surface_color(mat, u, v, *p, *n, *d, mat_i, mat_f, texels, light_f,
                                         shading, ambient)
                want = surface_color(mat, u, v, p, n, d, mat_i, mat_f, texels, light_f,
                                     shading, ambient)
                np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-9)
    # no lights at all: ambient only
    got = fast_surface_color(0, 0.0, 0.0, 0, 0, 0, 0, 0, 1, 0, 0, -1, mat_i, mat_f, texels,
                             np.zeros((0, 7), np.float32), shading, 0.25)
    want = surface_color(0, 0.0, 0.0, np.zeros(3), [0, 0, 1], [0, 0, -1], mat_i, mat_f, texels,
                         np.zeros((0, 7)), shading, 0.25)
    np.testing.assert_allclose(got, want, rtol=1e-7)


CAMERAS = [
    Camera(np.array([0.3, 1.0, 4.0]), np.array([-0.2, 0.6, -1.0]), np.array([0.1, 1.0, 0.0]),
           60.0, 7, 5, 0.5, 50.0),
    Camera(np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, -1.0]), np.array([0.0, 1.0, 0.0]),
           90.0, 1, 1, 0.1, 10.0),
    Camera(np.array([-2.0, 3.0, 1.0]), np.array([1.0, -1.0, 2.0]), np.array([0.0, 0.0, 1.0]),
           35.0, 3, 8, 2.0, 100.0),
]


@pytest.mark.parametrize("samples", [1, 2, 3])
@pytest.mark.parametrize("cam", CAMERAS)
def test_primary_rays_match_pixel_directions(cam, samples):
    origins, dirs = fast_primary_rays(cam, samples)
    want_o, want_d = primary_rays(cam, samples)
    assert origins.shape == want_o.shape and dirs.dtype == np.float32
    np.testing.assert_allclose(dirs, want_d, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(origins, want_o, rtol=1e-6, atol=1e-6)


def random_scene_arrays(rng, n_tri, n_objects, n_mirrors):
    corners = rng.uniform(-2, 2, (n_tri, 3, 3)).astype(np.float32)
    uvs = rng.uniform(-1, 2, (n_tri, 3, 2)).astype(np.float32)
    normals = rng.normal(size=(n_tri, 3, 3)).astype(np.float32)
    surface = rng.integers(0, n_objects + n_mirrors, n_tri).astype(np.int32)
    return corners, uvs, normals, surface


@pytest.mark.parametrize("shading", [UNLIT, LAMBERT])
@pytest.mark.parametrize("seed", range(2))
@pytest.mark.parametrize("per_pixel", [False, True])
def test_shade_pass_matches_twin(seed, shading, per_pixel):
    rng = np.random.default_rng(seed)
    mat_i, mat_f, texels = materials(rng)
    light_f = lights(rng)
    h, w, n_tri, n_objects, n_mirrors = 9, 11, 12, 3, 2
    corners, uvs, normals, surface = random_scene_arrays(rng, n_tri, n_objects, n_mirrors)
    material = rng.integers(0, len(mat_i), n_tri).astype(np.int32)
    tri = rng.integers(-1, n_tri, (h, w)).astype(np.int32)
    tri[0, :] = -1  # a row of background
    b = rng.dirichlet([1, 1, 1], (h, w)).astype(np.float32)
    b1, b2 = b[..., 1].copy(), b[..., 2].copy()
    b1[1, :3], b2[1, :3] = 0.0, 0.0  # on corner 0 exactly
    eye = rng.uniform(-3, 3, 3)
    background = rng.random(3).astype(np.float32)
    refl = rng.random((n_mirrors, 3)).astype(np.float32)
    refl[0] = 1.0
    base = rng.random((n_mirrors, 3)).astype(np.float32)
    rgb = np.empty((h, w, 3), np.float32)
    surf = np.empty((h, w), np.int32)
    # per pixel incoming rays (a curved mirror's reflected rays), or the eye's
    incoming = rng.normal(size=(h, w, 3)) if per_pixel else None
    dirs = incoming if per_pixel else np.zeros((1, 1, 3))
    _shade(tri, b1, b2, False, np.eye(4), corners, corners, uvs, normals, material, surface,
           n_objects, eye, dirs, per_pixel, mat_i, mat_f, texels, light_f, shading, 0.1,
           background, refl, base, rgb, surf, 2)
    want_rgb, want_surf = shade(tri, b1, b2, corners, uvs, normals, material, surface,
                                n_objects, eye, mat_i, mat_f, texels, light_f, shading, 0.1,
                                background, refl, base, incoming)
    np.testing.assert_array_equal(surf, want_surf)
    np.testing.assert_allclose(rgb, want_rgb, rtol=2e-5, atol=1e-6)
    # the stencilled kernel: the same pixels where the stencil is set, nothing else touched
    stencil = rng.random((h, w)) < 0.5
    stencil[0, :2] = True  # background under the stencil
    stencil[:, -1] = False
    rgb_s = np.full((h, w, 3), -7.0, np.float32)
    surf_s = np.full((h, w), -9, np.int32)
    head = (tri, b1, b2, corners, uvs, normals, material, surface, n_objects, eye)
    tail = (mat_i, mat_f, texels, light_f, shading, 0.1, background, refl, base)
    want_rgb_s, want_surf_s = shade_stencil(stencil, rgb_s, surf_s, *head, *tail, incoming)
    _shade_stencil(stencil, *head[:3], False, np.eye(4), corners, *head[3:], dirs, per_pixel, *tail,
                   rgb_s, surf_s, 0, h, 0, w, 2)
    np.testing.assert_array_equal(surf_s, want_surf_s)
    np.testing.assert_allclose(rgb_s, want_rgb_s, rtol=2e-5, atol=1e-6)
    assert (rgb_s[~stencil] == -7.0).all() and (surf_s[~stencil] == -9).all()
    # and bit for bit the full kernel's values where it shades
    np.testing.assert_array_equal(rgb_s[stencil], rgb[stencil])


@pytest.mark.parametrize("seed", range(3))
def test_shade_pass_recovering_barycentrics_matches_twin(seed):
    """_shade with recover=True (barycentrics from the clip-space corners, as after
    rasterize) against the twin shading the reference rasterizer's float64 barycentrics,
    on the pixels where both rasterizers see the same triangle (smooth materials: a
    checker's or texel's edge would turn a 1e-7 difference into a colour jump)."""
    rng = np.random.default_rng(seed)
    cam = camera()
    m = cam.projection_matrix() @ cam.view_matrix()
    corners = random_triangles(cam, 16, rng)
    n_tri, n_objects = 16, 3
    _, uvs, normals, _ = random_scene_arrays(rng, n_tri, n_objects, 0)
    surface = rng.integers(0, n_objects, n_tri).astype(np.int32)
    material = np.zeros(n_tri, np.int32)
    mat_i = np.zeros((1, 5), np.int32)
    mat_i[0, 0] = SOLID
    mat_f = np.array([[0.7, 0.4, 0.2, 0, 0, 0, 1, 1]], np.float32)  # (a scene's dtype)
    texels = np.zeros((1, 3), np.float32)
    light_f = lights(rng)
    flags = np.zeros(n_tri, np.uint8)
    got = fast_rasterize(corners, flags, m, W, H)
    assert got.recover
    tri_ref, b1_ref, b2_ref, _, ambiguous = rasterize(corners, flags, m, W, H)
    eye = cam.eye.astype(np.float64)
    background = np.zeros(3, np.float32)
    none3 = np.zeros((0, 3), np.float32)
    rgb = np.empty((H, W, 3), np.float32)
    surf = np.empty((H, W), np.int32)
    dummy = np.zeros((1, 1), np.float32)
    _shade(got.triangle, dummy, dummy, True, m, corners, corners, uvs, normals, material, surface,
           n_objects, eye, np.zeros((1, 1, 3)), False, mat_i, mat_f, texels, light_f, LAMBERT,
           0.1, background, none3, none3, rgb, surf, 2)
    want_rgb, _ = shade(tri_ref, b1_ref, b2_ref, corners, uvs, normals, material, surface,
                        n_objects, eye, mat_i, mat_f, texels, light_f, LAMBERT, 0.1,
                        background, none3, none3, None)
    same = (got.triangle == tri_ref) & ~ambiguous
    assert same.mean() > 0.95 and (tri_ref[same] >= 0).mean() > 0.3
    np.testing.assert_allclose(rgb[same], want_rgb[same], rtol=1e-5, atol=1e-6)
    # and the stored barycentrics (made on first use) are the recovered ones, to float32
    covered = same & (tri_ref >= 0)
    np.testing.assert_allclose(got.b1[covered], b1_ref[covered], atol=1e-5)
    np.testing.assert_allclose(got.b2[covered], b2_ref[covered], atol=1e-5)
    # the stencilled kernel, unlit shading, per-pixel incoming rays and interpolated uvs
    # (a bilinear texture: smooth in uv) take the same recovering route
    mat_i = np.array([[SOLID, 0, 0, 0, 0], [TEXTURE, 0, 2, 2, 1]], np.int32)
    mat_f = np.array([[0.7, 0.4, 0.2, 0, 0, 0, 1, 1], [0, 0, 0, 0, 0, 0, 1.5, 0.5]], np.float32)
    texels = rng.random((4, 3)).astype(np.float32)
    material = rng.integers(0, 2, n_tri).astype(np.int32)
    stencil = rng.random((H, W)) < 0.5
    incoming = rng.normal(size=(H, W, 3))
    for shading, per_pixel in ((UNLIT, False), (LAMBERT, False), (LAMBERT, True)):
        rgb_s = np.full((H, W, 3), -7.0, np.float32)
        surf_s = np.full((H, W), -9, np.int32)
        _shade_stencil(stencil, got.triangle, dummy, dummy, True, m, corners, corners, uvs,
                       normals, material, surface, n_objects, eye,
                       incoming if per_pixel else np.zeros((1, 1, 3)), per_pixel, mat_i, mat_f,
                       texels, light_f, shading, 0.1, background, none3, none3, rgb_s, surf_s,
                       0, H, 0, W, 2)
        want_rgb, _ = shade(tri_ref, b1_ref, b2_ref, corners, uvs, normals, material, surface,
                            n_objects, eye, mat_i, mat_f, texels, light_f, shading, 0.1,
                            background, none3, none3, incoming if per_pixel else None)
        inside = same & stencil
        np.testing.assert_allclose(rgb_s[inside], want_rgb[inside], rtol=1e-5, atol=1e-6)
        assert (rgb_s[~stencil] == -7.0).all() and (surf_s[~stencil] == -9).all()
        # a stencil inside a box (a virtual pass's): visiting only the box, on one worker,
        # gives the bytes of visiting the whole image on two
        inner = np.zeros_like(stencil)
        inner[5:17, 7:25] = stencil[5:17, 7:25]
        runs = []
        for box, threads in (((0, H, 0, W), 2), ((5, 17, 7, 25), 1)):
            rgb_b = np.full((H, W, 3), -7.0, np.float32)
            surf_b = np.full((H, W), -9, np.int32)
            _shade_stencil(inner, got.triangle, dummy, dummy, True, m, corners, corners, uvs,
                           normals, material, surface, n_objects, eye,
                           incoming if per_pixel else np.zeros((1, 1, 3)), per_pixel, mat_i,
                           mat_f, texels, light_f, shading, 0.1, background, none3, none3,
                           rgb_b, surf_b, *box, threads)
            runs.append((rgb_b, surf_b))
        np.testing.assert_array_equal(runs[0][0], runs[1][0])
        np.testing.assert_array_equal(runs[0][1], runs[1][1])
        np.testing.assert_array_equal(runs[0][0][inner], rgb_s[inner])
        assert (runs[1][0][~inner] == -7.0).all()


W, H = 32, 24


def camera():
    return Camera(np.array([0.3, 1.0, 4.0]), np.array([-0.2, 0.6, -1.0]),
                  np.array([0.1, 1.0, 0.0]), 60.0, W, H, 0.5, 50.0)


def random_triangles(cam, n, rng):
    """Triangles in front of the near plane, within far, over (and a little beyond) the view."""
    right, up, back = cam.basis()
    t = np.tan(np.radians(cam.fov_y) / 2)
    xy = rng.uniform(-1.1, 1.1, (n, 1, 2)) + rng.uniform(0.4, 1.5, (n, 1, 1)) * rng.uniform(
        -1, 1, (n, 3, 2))
    z = np.clip(rng.uniform(1.0, 12.0, (n, 1)) * rng.uniform(0.85, 1.15, (n, 3)), 1.0, 12.0)
    world = cam.eye + z[..., None] * (-back + xy[..., :1] * t * cam.aspect * right
                                      + xy[..., 1:] * t * up)
    return world.astype(np.float32)


def compare_raster(got, want, min_covered=0.2):
    tri, b1, b2, depth, ambiguous = want
    agree = got.triangle == tri
    assert np.all(agree | ambiguous)
    assert ambiguous.mean() <= 0.02
    both = agree & (tri >= 0)
    np.testing.assert_allclose(got.depth[both], depth[both], rtol=1e-4)
    np.testing.assert_allclose(got.b1[both], b1[both], atol=1e-4)
    np.testing.assert_allclose(got.b2[both], b2[both], atol=1e-4)
    assert np.all(np.isinf(got.depth[got.triangle < 0]))
    return (tri >= 0).mean()


@pytest.mark.parametrize("seed", range(4))
def test_rasterizer_with_mask_and_depth_floor_matches_twin(seed):
    rng = np.random.default_rng(seed)
    cam = camera()
    m = cam.projection_matrix() @ cam.view_matrix()
    corners = random_triangles(cam, 16, rng)
    flags = np.where(rng.random(16) < 0.25, FLAG_MIRROR, 0).astype(np.uint8)
    mask = rng.random((H, W)) < 0.7
    mask[:, :3] = False  # a bounding box smaller than the screen
    mask[-2:] = False
    floor = np.where(rng.random((H, W)) < 0.5, rng.uniform(0.0, 9.0, (H, W)), 0.0).astype(
        np.float32)
    got = fast_rasterize(corners, flags, m, W, H, mask=mask, depth_floor=floor)
    want = rasterize(corners, flags, m, W, H, mask=mask, depth_floor=floor)
    assert compare_raster(got, want) > 0.1  # not vacuous: the mask keeps ~2/3 of the view
    assert np.all(got.triangle[~mask] == -1)
    drawn = got.triangle >= 0
    assert np.all(got.depth[drawn] > floor[drawn])


def test_rasterizer_edge_masks_match_twin():
    """An empty mask draws nothing; a single-pixel mask draws one pixel; a floor beyond
    every triangle draws nothing."""
    rng = np.random.default_rng(5)
    cam = camera()
    m = cam.projection_matrix() @ cam.view_matrix()
    corners = random_triangles(cam, 12, rng)
    flags = np.zeros(12, np.uint8)
    empty = fast_rasterize(corners, flags, m, W, H, mask=np.zeros((H, W), bool))
    assert np.all(empty.triangle == -1) and np.all(np.isinf(empty.depth))
    full = fast_rasterize(corners, flags, m, W, H)
    y, x = np.argwhere(full.triangle >= 0)[len(np.argwhere(full.triangle >= 0)) // 2]
    one = np.zeros((H, W), bool)
    one[y, x] = True
    got = fast_rasterize(corners, flags, m, W, H, mask=one)
    compare_raster(got, rasterize(corners, flags, m, W, H, mask=one))
    assert got.triangle[y, x] == full.triangle[y, x] and (got.triangle >= 0).sum() == 1
    far = np.full((H, W), 1e6, np.float32)
    assert np.all(fast_rasterize(corners, flags, m, W, H, depth_floor=far).triangle == -1)


@pytest.mark.parametrize("cull", [CULL_NONE, CULL_BACK, CULL_FRONT])
@pytest.mark.parametrize("seed", range(2))
def test_rasterizer_culling_and_skip_match_twin(seed, cull):
    """Culling modes, FLAG_SKIP, FLAG_CULL_BACK and FLAG_CULL_FRONT (back or front faces
    of flagged triangles dropped whatever the mode) as the twin gives them."""
    rng = np.random.default_rng(seed + 20)
    cam = camera()
    m = cam.projection_matrix() @ cam.view_matrix()
    corners = random_triangles(cam, 16, rng)
    flags = np.where(rng.random(16) < 0.3, FLAG_SKIP, 0).astype(np.uint8)
    flags[rng.random(16) < 0.2] |= FLAG_MIRROR
    flags[rng.random(16) < 0.5] |= FLAG_CULL_BACK
    flags[rng.random(16) < 0.3] |= FLAG_CULL_FRONT
    got = fast_rasterize(corners, flags, m, W, H, cull=cull)
    compare_raster(got, rasterize(corners, flags, m, W, H, cull=cull))
    assert not np.isin(got.triangle, np.flatnonzero(flags & FLAG_SKIP)).any()


@pytest.mark.parametrize("seed", range(3))
def test_add_reflection_matches_twin(seed):
    rng = np.random.default_rng(seed)
    h, w = 13, 17
    rgb = rng.random((h, w, 3)).astype(np.float32)
    reflected = rng.random((h, w, 3)).astype(np.float32)
    stencil = np.zeros((h, w), np.bool_)
    stencil[3:9, 2:12] = rng.random((6, 10)) < 0.7
    stencil[3, 2] = stencil[8, 11] = True  # the box's corners
    reflectance = rng.random(3).astype(np.float32)
    want = naive_add_reflection(rgb, reflected, stencil, reflectance)
    got = rgb.copy()
    add_reflection(got, reflected, stencil, reflectance, 3, 9, 2, 12)
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("count", [1, 255, 256, 257, 1000])
def test_run_bounds_match_twin(count):
    rng = np.random.default_rng(count)
    corners = (rng.normal(size=(count, 3, 3)) * 10).astype(np.float32)
    if count > 300:
        corners[300, 1, 2] = np.nan  # a NaN corner poisons its run's axis, as numpy's min
    runs = (count + 255) // 256
    got = np.empty((runs, 6))
    run_bounds(corners, 256, got)
    np.testing.assert_array_equal(got, naive_run_bounds(corners, 256))


def test_prefetch_changes_no_value():
    """prefetch (and prefetch_write) is a hint: a gather with it reads the same values, and
    ids outside the array (-1 for no triangle, past its end) are no error."""
    from numba import njit

    from reflectcli.prefetch import prefetch, prefetch_write

    @njit
    def gather(a, ids, ahead):
        out = np.empty(ids.shape[0], np.float32)
        for i in range(ids.shape[0]):
            prefetch(a, ids[min(i + ahead, ids.shape[0] - 1)])
            prefetch(a, np.int32(-1))
            prefetch(a, a.shape[0] + 5)
            prefetch_write(out, i + ahead)
            prefetch_write(out, np.int32(-1))
            out[i] = a[ids[i], 1, 2]
        return out

    rng = np.random.default_rng(0)
    a = rng.random((500, 3, 3)).astype(np.float32)
    ids = rng.integers(0, 500, 300).astype(np.int32)
    np.testing.assert_array_equal(gather(a, ids, 8), a[ids, 1, 2])


def _pass_case(rng, counts):
    """Passes of random triangles (counts each), a label image of 0..P with the passes'
    boxes, and a depth floor."""
    cam = camera()
    m = cam.projection_matrix() @ cam.view_matrix()
    corners = np.concatenate([random_triangles(cam, n, rng) for n in counts])
    flags = np.where(rng.random(len(corners)) < 0.25, FLAG_MIRROR, 0).astype(np.uint8)
    flags[rng.random(len(corners)) < 0.05] |= FLAG_SKIP
    labels = rng.integers(0, len(counts) + 1, (H, W)).astype(np.uint8)
    labels[:, :2] = 0  # boxes smaller than the screen, and of different sizes
    labels[:3][labels[:3] == 1] = 0
    labels[:, -5:][labels[:, -5:] == 2] = 0
    boxes = np.zeros((len(counts), 4), np.int64)
    for p in range(len(counts)):
        ys, xs = np.nonzero(labels == p + 1)
        boxes[p] = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    floor = np.where(rng.random((H, W)) < 0.5, rng.uniform(0.0, 9.0, (H, W)), 0.0).astype(
        np.float32)
    return m, corners, flags, labels, boxes, floor, np.cumsum([0, *counts])


@pytest.mark.parametrize("seed", range(3))
def test_rasterize_passes_match_twin(seed):
    """Each pass of rasterize_passes, on its own label's pixels: the twin's triangles (ids
    offset by the pass's start), with and without a depth floor."""
    from reflectcli.raster.rasterize import RasterWorkspace
    from reflectcli.raster.rasterize.passes import rasterize_passes

    rng = np.random.default_rng(seed)
    m, corners, flags, labels, boxes, floor, starts = _pass_case(rng, (12, 16, 9))
    for depth_floor in (None, floor):
        ws = RasterWorkspace(outputs=True)
        got = rasterize_passes(corners, flags, m, W, H, starts, boxes, labels, depth_floor, ws)
        covered = 0.0
        for p in range(len(boxes)):
            s, e = starts[p], starts[p + 1]
            mine = labels == p + 1
            tri, b1, b2, depth, ambiguous = rasterize(corners[s:e], flags[s:e], m, W, H,
                                                      mask=mine, depth_floor=depth_floor)
            local = np.where(got.triangle >= 0, got.triangle - s, -1)
            assert np.all((local[mine] == tri[mine]) | ambiguous[mine])
            both = mine & (local == tri) & (tri >= 0)
            np.testing.assert_allclose(got.depth[both], depth[both], rtol=1e-4)
            assert np.all(np.isinf(got.depth[mine & (got.triangle < 0)]))
            assert np.all((got.triangle[mine] < 0) | ((got.triangle[mine] >= s)
                                                      & (got.triangle[mine] < e)))
            covered += (tri[mine] >= 0).mean()
        assert covered > 0.3  # not vacuous


@pytest.mark.parametrize("seed", range(2))
def test_rasterize_passes_are_the_passes_one_at_a_time(seed):
    """rasterize_passes gives every labelled pixel the very bytes (id offset, depth) that
    rasterize gives it in its pass alone (mask: its label, clear_outside False), for
    passes longer than a run of triangles, triangles the near plane cuts, and with the
    corners gathered from shared points as it draws (gather)."""
    from naive import gather_corners as naive_gather_corners

    from reflectcli.raster.rasterize import RasterWorkspace
    from reflectcli.raster.rasterize.constants import _CHUNK
    from reflectcli.raster.rasterize.passes import rasterize_passes

    rng = np.random.default_rng(seed)
    m, corners, flags, labels, boxes, floor, starts = _pass_case(rng, (_CHUNK + 37, 20, 300))
    cam = camera()
    _, _, back = cam.basis()
    cut = rng.choice(len(corners), 40, replace=False)  # one corner behind the eye
    corners[cut, 0] = (cam.eye + 0.5 * back).astype(np.float32)
    flags[cut] &= ~np.uint8(FLAG_SKIP)
    for depth_floor in (None, floor):
        ws = RasterWorkspace(outputs=True)
        got = rasterize_passes(corners, flags, m, W, H, starts, boxes, labels, depth_floor, ws)
        tri, depth = got.triangle.copy(), got.depth.copy()
        one = RasterWorkspace(outputs=True)
        for p in range(len(boxes)):
            s, e = starts[p], starts[p + 1]
            mine = labels == p + 1
            alone = fast_rasterize(corners[s:e], flags[s:e], m, W, H, mask=mine,
                                   depth_floor=depth_floor, workspace=one, clear_outside=False)
            want = np.where(alone.triangle >= 0, alone.triangle + s, -1).astype(np.int32)
            assert tri[mine].tobytes() == want[mine].tobytes()
            assert depth[mine].tobytes() == alone.depth[mine].tobytes()
    # the same triangles as indices into shared points, gathered as they are drawn (float32
    # points and int32 indices, as virtual's passes hand them)
    points = corners.reshape(-1, 3).copy()
    hidden = rng.random(len(points)) < 0.1
    index = np.arange(len(points), dtype=np.int32).reshape(-1, 3)
    surface = np.where(flags & FLAG_MIRROR, 7, 3).astype(np.int32)
    out_corners = np.empty_like(corners)
    out_flags = np.empty_like(flags)
    ws = RasterWorkspace(outputs=True)
    gathered = rasterize_passes(out_corners, out_flags, m, W, H, starts, boxes, labels, floor,
                                ws, gather=(points, hidden, index, surface, 5))
    want_corners, want_flags = naive_gather_corners(points, hidden, index, surface, 5)
    assert out_corners.tobytes() == want_corners.tobytes()
    assert out_flags.tobytes() == want_flags.tobytes()
    plain = rasterize_passes(want_corners, want_flags, m, W, H, starts, boxes, labels, floor,
                             RasterWorkspace(outputs=True))
    on = labels > 0
    assert gathered.triangle[on].tobytes() == plain.triangle[on].tobytes()
    assert gathered.depth[on].tobytes() == plain.depth[on].tobytes()


@pytest.mark.parametrize("shading", [UNLIT, LAMBERT])
def test_shading_that_merges_the_threads_buffers_is_merge_then_shade(shading):
    """_shade_stencil_resolving (rasterize_passes(resolve=False)'s buffers merged row by
    row as the rows are shaded): the very ids, depths, colours and surface ids of
    _resolve, then _shade_stencil (each held to its twin), lit with per-pixel rays and
    unlit, at 1 and 2 threads."""
    import numba

    from reflectcli.raster.rasterize import RasterWorkspace
    from reflectcli.raster.rasterize.passes import rasterize_passes
    from reflectcli.raster.shade import _shade_stencil_resolving

    rng = np.random.default_rng(11)
    m, corners, flags, labels, boxes, floor, starts = _pass_case(rng, (300, 40, 90))
    n_tri, n_objects = len(corners), 3
    _, uvs, normals, surface = random_scene_arrays(rng, n_tri, n_objects, 2)
    mat_i, mat_f, texels = materials(rng)
    material = rng.integers(0, len(mat_i), n_tri).astype(np.int32)
    light_f = lights(rng)
    eye = camera().eye.astype(np.float64)
    background = rng.random(3).astype(np.float32)
    refl = rng.random((2, 3)).astype(np.float32)
    base = rng.random((2, 3)).astype(np.float32)
    stencil = labels > 0
    y0, y1, x0, x1 = boxes[:, 0].min(), boxes[:, 1].max(), boxes[:, 2].min(), boxes[:, 3].max()
    dirs = rng.normal(size=(H, W, 3))
    dummy = np.zeros((1, 1), np.float32)
    before = numba.get_num_threads()
    try:
        for threads in (1, 2):
            numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
            results = []
            for resolve in (True, False):
                ws = RasterWorkspace(outputs=True)
                ws.get("tri", (H, W), np.int32)[:] = -5  # outside the box: left as found
                out = rasterize_passes(corners, flags, m, W, H, starts, boxes, labels, floor, ws,
                                       resolve=resolve)
                buffers, pending = (out, None) if resolve else out
                rgb = np.full((H, W, 3), -7.0, np.float32)
                surf = np.full((H, W), -9, np.int32)
                args = (stencil, buffers.triangle, dummy, dummy, True, buffers.clip_from_world,
                        buffers.corners, corners, uvs, normals, material, surface, n_objects,
                        eye, dirs, True, mat_i, mat_f, texels, light_f, shading, 0.1,
                        background, refl, base, rgb, surf, y0, y1, x0, x1, threads)
                if resolve:
                    _shade_stencil(*args)
                else:
                    _shade_stencil_resolving(*args, *pending)
                results.append((buffers.triangle.copy(), buffers.depth.copy(), rgb, surf))
            (tri_a, depth_a, rgb_a, surf_a), (tri_b, depth_b, rgb_b, surf_b) = results
            assert tri_a.tobytes() == tri_b.tobytes()
            inside = np.zeros((H, W), bool)
            inside[y0:y1, x0:x1] = True
            assert depth_a[inside].tobytes() == depth_b[inside].tobytes()
            assert rgb_a.tobytes() == rgb_b.tobytes() and surf_a.tobytes() == surf_b.tobytes()
            assert (tri_a[stencil] >= 0).mean() > 0.3
    finally:
        numba.set_num_threads(before)
