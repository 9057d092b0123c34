"""The ray tracer's hit resolution (resolve_range, _pick) against its slow twin."""

from __future__ import annotations

import numba
import numpy as np
import pytest
from conftest import compiled_only
from naive import compact, embreex_hits, pick, primary_rays, resolve, wave
from naive import planar_units as planar_units_twin
from test_shading_raster_twins import CAMERAS, lights, materials

from reflectcli.scene.types import CYLINDER, LAMBERT, MESH, MIRROR_PARAMS, PLANAR, SPHERE, UNLIT
from reflectcli.trace.analytic import quad_edges, screen_boxes
from reflectcli.trace.rays import camera_rays
from reflectcli.trace.resolve import _pick, planar_units, resolve_range
from reflectcli.trace.wave import trace_segments


@compiled_only
def test_pick_matches_twin_on_ties_and_misses():
    inf = np.float32(np.inf)
    values = [np.float32(x) for x in (1.0, 2.0, 1.0 / (1.0 - 1e-4), 0.5, 0.0)] + [inf]
    for t_o in values:
        for t_m in values:
            for t_a in values:
                assert _pick(t_o, t_m, t_a) == pick(t_o, t_m, t_a), (t_o, t_m, t_a)


def mirror_params(rng):
    kind = np.array([PLANAR, SPHERE, CYLINDER, MESH], np.int32)
    params = np.zeros((4, MIRROR_PARAMS))
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    params[0, :4] = (*n, rng.normal())
    params[1, :4] = (*rng.normal(size=3), 0.7)
    a = rng.normal(size=3)
    params[2, :8] = (*rng.normal(size=3), *(a / np.linalg.norm(a)), 0.5, 2.0)
    return kind, params


@pytest.mark.parametrize("seed", range(3))
def test_planar_units_match_twin(seed):
    """The planar mirrors' unit normals resolve_range reads (made once a frame), against the
    twin's normal over its length, on random normals of any length and kind."""
    rng = np.random.default_rng(seed)
    kind = rng.choice(np.array([PLANAR, SPHERE, CYLINDER, MESH], np.int32), 12)
    params = np.zeros((12, MIRROR_PARAMS))
    params[:, :3] = rng.normal(size=(12, 3)) * 10.0 ** rng.uniform(-3, 3, (12, 1))
    got, want = planar_units(kind, params), planar_units_twin(kind, params)
    planar = kind == PLANAR
    np.testing.assert_allclose(got[planar], want[planar], rtol=1e-15, atol=0)
    np.testing.assert_allclose(np.linalg.norm(got[planar], axis=1), 1.0, rtol=1e-15)
    assert planar_units(kind[:0], params[:0]).shape == (0, 3)


@pytest.mark.parametrize("shading", [UNLIT, LAMBERT])
@pytest.mark.parametrize("follow", [True, False])
@pytest.mark.parametrize("seed", range(3))
def test_resolve_matches_twin(seed, follow, shading):
    rng = np.random.default_rng(seed)
    mat_i, mat_f, texels = materials(rng)
    light_f = lights(rng)
    n, n_obj_tri, n_mirror_tri, n_objects = 700, 7, 5, 3
    kind, params = mirror_params(rng)
    origins = rng.uniform(-3, 3, (n, 3)).astype(np.float32)
    dirs = rng.normal(size=(n, 3)).astype(np.float32)
    weight = rng.random((n, 3)).astype(np.float32)
    weight[:5] = 0.0  # dead weight: no reflected ray survives
    slot = rng.permutation(n).astype(np.int64)
    slot[::10] = slot[1::10]  # several rays into one slot (samples of a pixel)

    def times(p_miss):
        t = rng.uniform(0.1, 5.0, n).astype(np.float32)
        t[rng.random(n) < p_miss] = np.inf
        return t

    t_o, t_m, t_a = times(0.4), times(0.6), times(0.6)
    t_m[10:20] = t_o[10:20]  # exact ties: the mirror wins
    t_a[20:30] = t_m[20:30]
    t_o[30:40] = t_m[30:40] = t_a[30:40] = np.inf  # misses
    p_o = rng.integers(0, n_obj_tri, n).astype(np.int32)
    p_m = rng.integers(0, n_mirror_tri, n).astype(np.int32)
    k_a = rng.integers(0, 3, n).astype(np.int32)  # an analytic mirror (not the mesh one)
    uv = rng.dirichlet([1, 1, 1], (2, n)).astype(np.float32)
    u_o, v_o, u_m, v_m = uv[0, :, 1], uv[0, :, 2], uv[1, :, 1], uv[1, :, 2]
    corners = rng.uniform(-2, 2, (n_obj_tri, 3, 3)).astype(np.float32)
    uvs = rng.uniform(-1, 2, (n_obj_tri, 3, 2)).astype(np.float32)
    normals = rng.normal(size=(n_obj_tri, 3, 3)).astype(np.float32)
    material = rng.integers(0, len(mat_i), n_obj_tri).astype(np.int32)
    surface = rng.integers(0, n_objects, n_obj_tri).astype(np.int32)
    m_corners = rng.uniform(-2, 2, (n_mirror_tri, 3, 3)).astype(np.float32)
    m_normals = rng.normal(size=(n_mirror_tri, 3, 3)).astype(np.float32)
    m_surface = np.full(n_mirror_tri, n_objects + 3, np.int32)  # the mesh mirror
    m_refl = rng.random((4, 3)).astype(np.float32)
    m_refl[1] = (0.0, 0.5, 0.0)
    m_base = rng.random((4, 3)).astype(np.float32)
    background = rng.random(3).astype(np.float32)
    color = rng.random((n, 3)).astype(np.float32)
    surfaces = (corners, uvs, normals, material, surface, m_corners, m_normals, m_surface, kind,
                params, m_refl, m_base, n_objects, mat_i, mat_f, texels, light_f, shading, 0.1,
                background, planar_units(kind, params))
    hits = ((t_o, p_o, u_o, v_o), (t_m, p_m, u_m, v_m), (t_a, k_a))

    def run(weight, slot, color, first, lo=0, hi=n, start=3):
        """resolve_range on rays lo .. hi - 1, reflected rays written from `start` on:
        (hit_t, hit_surface, emitted count, reflected origins, dirs, weights, slots)."""
        out = (np.full(n, -5.0, np.float32), np.full(n, -5, np.int32))
        rays_out = [np.full((n + start, 3), np.nan, np.float32) for _ in range(3)]
        rays_out.append(np.full(n + start, -9, np.int64))
        count = resolve_range(lo, hi, (origins, dirs, weight, slot), *hits, surfaces, follow,
                              color, out, tuple(rays_out), start, first)
        # nothing written outside the range / past the emitted rays
        assert (out[0][:lo] == -5).all() and (out[0][hi:] == -5).all()
        assert (rays_out[3][:start] == -9).all() and (rays_out[3][start + count:] == -9).all()
        return (*out, count, *(a[start:start + count] for a in rays_out))

    got_color = color.copy()
    hit_t_got, surface_got, count, *emitted = run(weight, slot, got_color, False)
    args = (origins, dirs, weight, slot, t_o, p_o, u_o, v_o, t_m, p_m, u_m, v_m, t_a, k_a,
            corners, uvs, normals, material, surface, m_corners, m_normals, m_surface, kind,
            params, m_refl, m_base, n_objects, mat_i, mat_f, texels, light_f, shading, 0.1,
            background, follow)
    want_color, hit_t, hit_surface, alive, next_o, next_d, next_w = resolve(
        *args, color.astype(np.float64))
    np.testing.assert_allclose(got_color, want_color, rtol=2e-5, atol=1e-6)
    np.testing.assert_allclose(hit_t_got, hit_t, rtol=1e-7)
    np.testing.assert_array_equal(surface_got, hit_surface)
    # the reflected rays: those of the twin's living rays, in order, with their slots
    assert count == alive.sum()
    assert alive.any() == follow and not alive[:5].any()
    want_o, want_d, want_w, want_slot = compact(alive, next_o, next_d, next_w, slot)
    np.testing.assert_allclose(emitted[0], want_o, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(emitted[1], want_d, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(emitted[2], want_w, rtol=1e-6)
    np.testing.assert_array_equal(emitted[3], want_slot)
    # a part of the rays: the same answers for them, nothing else written
    part_color = color.copy()
    part = run(weight, slot, part_color, False, lo=50, hi=150, start=0)
    np.testing.assert_array_equal(part[0][50:150], hit_t_got[50:150])
    assert part[2] == alive[50:150].sum()
    np.testing.assert_array_equal(part[6], want_slot[alive[:50].sum():][:part[2]])
    touched = np.zeros(n, bool)
    touched[slot[50:150]] = True
    np.testing.assert_array_equal(part_color[~touched], color[~touched])
    # the first wave: weights ones and slots the identity, never read (garbage here), color
    # rows written over whatever they held; the same as the general route given those
    ones = np.ones((n, 3), np.float32)
    want_first = np.zeros((n, 3), np.float32)
    want = run(ones, np.arange(n, dtype=np.int64), want_first, False)
    got_first = np.full((n, 3), np.nan, np.float32)
    got = run(np.full((n, 3), np.nan, np.float32), np.full(n, -(10 ** 9), np.int64), got_first,
              True)
    np.testing.assert_array_equal(got_first, want_first)
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(g, w)


def wave_scene(rng, shading):
    """A small scene for trace_segments: 40 object triangles, a mesh mirror of 6 triangles, and
    planar, sphere and cylinder mirrors: (object corners, mirror corners, kind, params,
    resolve_range's surfaces)."""
    mat_i, mat_f, texels = materials(rng)
    n_tri, n_mirror_tri, n_objects = 40, 6, 3
    corners = rng.uniform(-3, 3, (n_tri, 3, 3)).astype(np.float32)
    uvs = rng.uniform(-1, 2, (n_tri, 3, 2)).astype(np.float32)
    normals = rng.normal(size=(n_tri, 3, 3)).astype(np.float32)
    material = rng.integers(0, len(mat_i), n_tri).astype(np.int32)
    surface = rng.integers(0, n_objects, n_tri).astype(np.int32)
    m_corners = rng.uniform(-3, 3, (n_mirror_tri, 3, 3)).astype(np.float32)
    m_normals = rng.normal(size=(n_mirror_tri, 3, 3)).astype(np.float32)
    m_surface = np.full(n_mirror_tri, n_objects + 3, np.int32)
    kind = np.array([PLANAR, SPHERE, CYLINDER, MESH], np.int32)
    params = np.zeros((4, MIRROR_PARAMS))
    n = np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])
    c00 = np.array([-1.5, -1.0, -2.0])
    e1 = np.cross([0.0, 1.0, 0.0], n) * 2.5 / np.linalg.norm(np.cross([0.0, 1.0, 0.0], n))
    e2 = np.cross(n, e1) * 0.8
    params[0, :16] = (*n, -n @ c00, *c00, *(c00 + e1), *(c00 + e1 + e2), *(c00 + e2))
    params[1, :4] = (1.0, 1.5, 0.5, 0.7)
    a = np.array([0.2, 1.0, -0.3]) / np.linalg.norm([0.2, 1.0, -0.3])
    params[2, :8] = (-1.0, -2.0, 1.0, *a, 0.5, 2.0)
    m_refl = rng.random((4, 3)).astype(np.float32)
    m_refl[1] = (0.0, 0.5, 0.0)
    m_base = rng.random((4, 3)).astype(np.float32)
    background = rng.random(3).astype(np.float32)
    surfaces = (corners, uvs, normals, material, surface, m_corners, m_normals, m_surface, kind,
                params, m_refl, m_base, n_objects, mat_i, mat_f, texels, lights(rng), shading,
                0.1, background, planar_units(kind, params))
    return corners, m_corners, kind, params, surfaces


def run_wave(scenes, kind, params, surfaces, counts, seg_len, rows_per_seg, cam, rays, tfar,
             follow, bounce, near, color, given=None, boxes=None, per_worker=False):
    """One wave of trace_segments, fresh outputs: (hit_t (depth: t + near on the primary wave),
    hit_surface, out rays, out counts, reflected_hit). `given`: the objects' and mirrors'
    hits, filled before (the embreex fallback), instead of the scenes' handles."""
    n = seg_len * len(counts)
    hits = [tuple(np.full(n, x, dt) for x, dt in ((7.0, np.float32), (-7, np.int32),
                                                   (7.0, np.float32), (7.0, np.float32)))
            for _ in range(2)]
    sides = []
    for s, h, g in zip(scenes, hits, given or (None, None), strict=True):
        if g is not None:
            for a, b in zip(h, g, strict=True):
                a[:] = b
        sides.append((0 if given else s.handle, given is not None and s.count > 0, *h))
    if boxes is None:
        boxes = np.tile(np.array([0, cam[5], 0, cam[6]], np.int64), (len(kind), 1))
    analytic = (True, kind, params, quad_edges(kind, params), boxes, np.full(n, 7.0, np.float32),
                np.full(n, -7, np.int32))
    out_hits = (np.full(n, -5.0, np.float32), np.full(n, -5, np.int32))
    out_rays = (np.full((n, 3), np.nan, np.float32), np.full((n, 3), np.nan, np.float32),
                np.full((n, 3), np.nan, np.float32), np.full(n, -9, np.int64))
    out_counts = counts.copy()
    reflected_hit = np.zeros(color.shape[0], np.float32)
    traced = np.full((len(counts), bounce + 2), -1, np.int64)
    buffers = (rays, out_rays) if bounce % 2 == 0 else (out_rays, rays)
    trace_segments(seg_len, out_counts, rows_per_seg, cam, buffers,
                   np.array([tfar, tfar], np.float32), *sides, analytic, surfaces,
                   (bounce, bounce), bounce + 1 if follow else bounce, (out_hits, out_hits),
                   color, np.float32(near), reflected_hit, traced, numba.get_num_threads(),
                   per_worker)
    np.testing.assert_array_equal(traced[:, bounce], counts)
    assert (traced[:, :bounce] == -1).all() and (traced[:, bounce + 1:] == -1).all()
    return (*out_hits, out_rays, out_counts, reflected_hit)


def check_wave(got, want, counts, seg_len, n_colors, color, want_color, primary=False):
    """A wave's outputs against the wave twin's, on the rays the twin calls clear (the
    primary wave's t is depth)."""
    rows, _, hit_t, hit_surface, alive, emitted, depth, marginal = want
    g_t, g_surface, g_rays, g_counts, _ = got
    clear = ~marginal
    assert clear.mean() > 0.9
    np.testing.assert_array_equal(g_surface[rows][clear], hit_surface[clear])
    np.testing.assert_allclose(g_t[rows][clear], (depth if primary else hit_t)[clear],
                               rtol=1e-5)
    # every emitted ray of a clear ray, found by its slot (slots are distinct here)
    assert (g_counts == [len(e[3]) for e in emitted]).sum() >= len(counts) - (~clear).sum()
    clear_slots = set(rays_slot for rays_slot in np.asarray(want[0])[clear])
    for k, e in enumerate(emitted):
        lo = k * seg_len
        got_slots = list(g_rays[3][lo:lo + g_counts[k]])
        assert (g_rays[3][lo + g_counts[k]:lo + seg_len] == -9).all()
        for j, s in enumerate(e[3]):
            if s not in clear_slots:
                continue
            at = lo + got_slots.index(s)
            np.testing.assert_allclose(g_rays[0][at], e[0][j], rtol=1e-5, atol=1e-5)
            np.testing.assert_allclose(g_rays[1][at], e[1][j], rtol=1e-5, atol=1e-6)
            np.testing.assert_allclose(g_rays[2][at], e[2][j], rtol=1e-6)
    touched = np.zeros(n_colors, bool)
    touched[rows[clear]] = True
    np.testing.assert_allclose(color[touched], want_color[touched], rtol=2e-5, atol=1e-6)
    return clear


@compiled_only
@pytest.mark.parametrize("shading", [UNLIT, LAMBERT])
@pytest.mark.parametrize("seed", range(2))
def test_wave_matches_twin(seed, shading):
    """A bounce wave over ragged segments (one empty) on the Embree path, and the same wave
    with the hits given (the embreex fallback): the twin's answers, and the same bytes."""
    from reflectcli.trace.embree import TriangleScene

    rng = np.random.default_rng(seed)
    corners, m_corners, kind, params, surfaces = wave_scene(rng, shading)
    seg_len, counts = 128, np.array([128, 0, 77, 128, 5], np.int64)
    n = seg_len * len(counts)
    origins = rng.uniform(-4, 4, (n, 3)).astype(np.float32)
    goal = rng.uniform(-2, 2, (n, 3))
    dirs = ((goal - origins) * rng.uniform(0.3, 2.0, (n, 1))).astype(np.float32)
    weight = rng.random((n, 3)).astype(np.float32)
    weight[:3] = 0.0
    slot = rng.permutation(n).astype(np.int64)  # distinct: a wave of one sample per pixel
    rays = (origins, dirs, weight, slot)
    scenes = (TriangleScene(corners), TriangleScene(m_corners))
    start = rng.random((n, 3)).astype(np.float32)
    color = start.copy()
    cam = camera_rays(CAMERAS[0], 1)
    got = run_wave(scenes, kind, params, surfaces, counts, seg_len, 0, cam, rays, 30.0, True,
                   1, 0.5, color)
    want_color = start.astype(np.float64)
    want = wave(counts, seg_len, rays, 30.0, corners, m_corners, kind, params, surfaces, True,
                1, 0.5, want_color)
    clear = check_wave(got, want, counts, seg_len, n, color, want_color)
    rows, hit_surface = want[0], want[3]
    hit = np.zeros(n, bool)
    hit[slot[rows][clear & (hit_surface >= 0)]] = True
    miss = np.zeros(n, bool)
    miss[slot[rows][clear & (hit_surface < 0)]] = True
    assert (got[4][hit] == 1).all() and (got[4][miss] == 0).all()  # first bounce: marked
    assert (got[4][np.setdiff1d(np.arange(n), slot[rows])] == 0).all()
    # the hits given (the embreex fallback): the same bytes
    given = [embreex_hits(c, origins, dirs, np.full(n, 30.0, np.float32))
             for c in (corners, m_corners)]
    color2 = start.copy()
    got2 = run_wave(scenes, kind, params, surfaces, counts, seg_len, 0, cam, rays, 30.0, True,
                    1, 0.5, color2, given=given)
    np.testing.assert_array_equal(color2, color)
    for a, b in zip(got2, got, strict=True):
        for x, y in zip(a if isinstance(a, tuple) else (a,), b if isinstance(b, tuple) else (b,),
                        strict=True):
            np.testing.assert_array_equal(x[np.isfinite(x) | ~np.isnan(x)],
                                          y[np.isfinite(y) | ~np.isnan(y)])


@compiled_only
@pytest.mark.parametrize("samples", [1, 2])
def test_primary_wave_matches_twin(samples):
    """The primary wave makes its rays (the twin's primary rays) and writes depth and ids."""
    from reflectcli.camera import Camera
    from reflectcli.trace.embree import TriangleScene

    rng = np.random.default_rng(7 + samples)
    corners, m_corners, kind, params, surfaces = wave_scene(rng, UNLIT)
    camera = Camera(np.array([0.5, 0.8, 6.0]), np.array([0.0, 0.0, 0.0]),
                    np.array([0.0, 1.0, 0.0]), 60.0, 13, 9, 0.5, 40.0)
    per_row = camera.width * samples * samples
    rows_per_seg, n = 2, camera.height * per_row
    seg_len = rows_per_seg * per_row
    counts = np.full(-(-camera.height // rows_per_seg), seg_len, np.int64)
    counts[-1] = n - seg_len * (len(counts) - 1)
    size = seg_len * len(counts)
    rays = (np.full((size, 3), np.nan, np.float32), np.full((size, 3), np.nan, np.float32),
            np.full((size, 3), np.nan, np.float32), np.full(size, -(10 ** 9), np.int64))
    scenes = (TriangleScene(corners), TriangleScene(m_corners))
    color = np.full((size, 3), np.nan, np.float32)
    tfar = camera.far - camera.near
    boxes = screen_boxes(kind, params, camera)
    assert (boxes[:3, 1] - boxes[:3, 0] < camera.width).any()  # some rays skip a mirror
    got = run_wave(scenes, kind, params, surfaces, counts, seg_len, rows_per_seg,
                   camera_rays(camera, samples), rays, tfar, True, 0, camera.near, color,
                   boxes=boxes)
    want_o, want_d = primary_rays(camera, samples)
    np.testing.assert_allclose(rays[0][:n], want_o, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(rays[1][:n], want_d, rtol=1e-6, atol=1e-6)
    given = (rays[0], rays[1], np.ones((size, 3), np.float32), np.arange(size))
    want_color = np.zeros((size, 3))
    want = wave(counts, seg_len, given, tfar, corners, m_corners, kind, params, surfaces, True,
                0, camera.near, want_color)
    clear = check_wave(got, want, counts, seg_len, size, color, want_color, primary=True)
    rows = want[0]
    np.testing.assert_array_equal(got[1][rows][clear], want[3][clear])  # ids
    np.testing.assert_allclose(got[0][rows][clear], want[6][clear], rtol=1e-5)  # depth
    assert np.isinf(got[0][rows][clear & (want[3] < 0)]).all()
    assert (got[4] == 0).all()  # reflected_hit: the first bounce's
    # per-thread scratch: the rays made and traced in a thread's rows; the same bytes out
    scratch = tuple(np.full_like(a, np.nan if a.dtype.kind == "f" else -(10 ** 9))
                    for a in rays)
    color2 = np.full((size, 3), np.nan, np.float32)
    got2 = run_wave(scenes, kind, params, surfaces, counts, seg_len, rows_per_seg,
                    camera_rays(camera, samples), scratch, tfar, True, 0, camera.near, color2,
                    boxes=boxes, per_worker=True)
    assert color2[:n].tobytes() == color[:n].tobytes()
    for a, b in ((got2[0], got[0]), (got2[1], got[1]), (got2[3], got[3]), (got2[4], got[4])):
        assert a[:n].tobytes() == b[:n].tobytes()
