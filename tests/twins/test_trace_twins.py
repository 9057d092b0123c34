"""The ray tracer's hit resolution (_resolve, _pick) against its slow twin."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import compiled_only
from naive import compact, pick, resolve
from test_shading_raster_twins import lights, materials

from reflectcli.scene.types import CYLINDER, LAMBERT, MESH, MIRROR_PARAMS, PLANAR, SPHERE, UNLIT
from reflectcli.trace.tracer import _compact, _pick, _resolve


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


@pytest.mark.parametrize("shading", [UNLIT, LAMBERT])
@pytest.mark.parametrize("follow", [True, False])
@pytest.mark.parametrize("seed", range(3))
def test_resolve_matches_twin(seed, follow, shading):
    rng = np.random.default_rng(seed)
    mat_i, mat_f, texels = materials(rng)
    light_f = lights(rng)
    n, n_obj_tri, n_mirror_tri, n_objects = 200, 7, 5, 3
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
    out = [np.empty(n, np.float32), np.empty(n, np.int32), np.zeros(n, np.bool_),
           np.full((n, 3), np.nan, np.float32), np.full((n, 3), np.nan, np.float32),
           np.full((n, 3), np.nan, np.float32)]
    args = (origins, dirs, weight, slot, t_o, p_o, u_o, v_o, t_m, p_m, u_m, v_m, t_a, k_a,
            corners, uvs, normals, material, surface, m_corners, m_normals, m_surface, kind,
            params, m_refl, m_base, n_objects, mat_i, mat_f, texels, light_f, shading, 0.1,
            background, follow)
    got_color = color.copy()
    _resolve(*args, got_color, *out, False)
    want_color, hit_t, hit_surface, alive, next_o, next_d, next_w = resolve(
        *args, color.astype(np.float64))
    np.testing.assert_allclose(got_color, want_color, rtol=2e-5, atol=1e-6)
    np.testing.assert_allclose(out[0], hit_t, rtol=1e-7)
    np.testing.assert_array_equal(out[1], hit_surface)
    np.testing.assert_array_equal(out[2], alive)
    assert alive.any() == follow and not alive[:5].any()
    a = alive
    np.testing.assert_allclose(out[3][a], next_o[a], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(out[4][a], next_d[a], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(out[5][a], next_w[a], rtol=1e-6)
    # the first wave: weights ones and slots the identity, never read (garbage here), color
    # rows written over whatever they held; the same as the general route given those
    ones = np.ones((n, 3), np.float32)
    first_args = (*args[:2], ones, np.arange(n, dtype=np.int64), *args[4:])
    want_first = [np.zeros((n, 3), np.float32)] + [a.copy() for a in out]
    _resolve(*first_args, want_first[0], *want_first[1:], False)
    garbage = (*args[:2], np.full((n, 3), np.nan, np.float32), np.full(n, -(10 ** 9), np.int64),
               *args[4:])
    got_first = [np.full((n, 3), np.nan, np.float32)] + [a.copy() for a in out]
    _resolve(*garbage, got_first[0], *got_first[1:], True)
    for got, want in zip(got_first, want_first, strict=True):
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("n", [0, 1, 7, 1000])
def test_compact_matches_twin(n):
    rng = np.random.default_rng(n)
    alive = rng.random(n) < 0.4
    if n:
        alive[0], alive[-1] = True, n > 1 and alive[-1]
    arrays = [rng.normal(size=(n, 3)).astype(np.float32) for _ in range(3)]
    slot = rng.permutation(n).astype(np.int64)
    m = int(alive.sum())
    out = [np.full((m + 2, 3), -7.0, np.float32) for _ in range(3)]
    out_slot = np.full(m + 2, -9, np.int64)
    assert _compact(alive, *arrays, slot, *out, out_slot) == m
    for got, want in zip([*out, out_slot], compact(alive, *arrays, slot), strict=True):
        np.testing.assert_array_equal(got[:m], want)
        assert (got[m:] < -6).all()  # nothing written past the alive rows
