"""Embree and the analytic intersectors (sphere, cylinder, planar quad) against float64
closed forms."""

from __future__ import annotations

import numpy as np
from conftest import compiled_only
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from naive import (
    T_REL,
    analytic_nearest,
    brute_force,
    cylinder_closed_form,
    sphere_closed_form,
)

from reflectcli.scene.types import CYLINDER, MESH, MIRROR_PARAMS, PLANAR, SPHERE
from reflectcli.trace import embree
from reflectcli.trace.analytic import intersect_analytic
from reflectcli.trace.embree import TriangleScene

f32 = st.floats(-1.0, 1.0, allow_nan=False, width=32)


soups = st.integers(1, 12).flatmap(lambda n: arrays(np.float32, (n, 3, 3), elements=f32))
ray_sets = st.integers(1, 64).flatmap(lambda n: arrays(np.float32, (n, 6), elements=f32))


@settings(max_examples=300, deadline=None)
@given(soups, ray_sets, st.sampled_from([np.inf, 2.0]), st.integers(0, 2**32 - 1))
def test_embree_matches_moller_trumbore(corners, rays, far, seed):
    # sliver triangles are numerically ambiguous everywhere; keep triangles of fair area
    area2 = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]),
                           axis=1)
    corners = corners[area2 > 1e-2]
    origins = 2.0 * rays[:, :3]
    d = rays[:, 3:]
    keep = np.linalg.norm(d, axis=1) > 0.05
    origins, d = origins[keep], d[keep]
    if len(corners) == 0 or len(origins) == 0:
        return
    # aim half the rays at a triangle's interior so that hits are common
    rng = np.random.default_rng(seed)
    aim = rng.random(len(origins)) < 0.5
    tri = rng.integers(0, len(corners), len(origins))
    bary = rng.dirichlet([1, 1, 1], len(origins))
    goal = np.einsum("rk,rkc->rc", bary, corners[tri].astype(np.float64))
    d = np.where(aim[:, None], (goal - origins) * rng.uniform(0.3, 2.0, (len(d), 1)),
                 d).astype(np.float32)
    keep = np.linalg.norm(d, axis=1) > 0.05
    origins, d = origins[keep], d[keep]
    if len(origins) == 0:
        return
    tfar = np.full(len(origins), far, np.float32)
    scene = TriangleScene(corners)
    t, prim, u, v = scene.intersect(origins, d, tfar)
    bt, bprim, bu, bv, ambiguous = brute_force(corners, origins, d, tfar.astype(np.float64))
    clear = ~ambiguous
    np.testing.assert_array_equal(prim[clear], bprim[clear])
    hit = clear & (bprim >= 0)
    # Embree works in float32: positions carry a few ulps of the coordinates' magnitude, and
    # a grazing ray turns that into a larger error along the ray (1 / cosine) and across the
    # triangle (1 / its height). Tolerances: the stated relative ones plus that conditioning.
    eps = 8 * np.finfo(np.float32).eps * (1.0 + max(np.abs(corners).max(),
                                                    np.abs(origins).max()))
    c64 = corners.astype(np.float64)
    e1, e2 = c64[:, 1] - c64[:, 0], c64[:, 2] - c64[:, 0]
    cross = np.cross(e1, e2)
    area2 = np.linalg.norm(cross, axis=1)
    longest = np.linalg.norm(np.stack([e1, e2, e2 - e1], 1), axis=2).max(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):  # misses: inf - inf, 0 / 0
        p = np.maximum(bprim, 0)
        dn = np.linalg.norm(d.astype(np.float64), axis=1)
        cosine = np.abs(np.einsum("rk,rk->r", d, cross[p])) / (dn * area2[p])
        t_tol = T_REL * bt + eps / (dn * cosine)
        b_tol = 1e-4 + eps / cosine * longest[p] / area2[p]
        assert np.all(np.abs(t - bt)[hit] <= t_tol[hit]), (t[hit], bt[hit])
        assert np.all(np.abs(u - bu)[hit] <= b_tol[hit]), (u[hit], bu[hit])
        assert np.all(np.abs(v - bv)[hit] <= b_tol[hit]), (v[hit], bv[hit])
    assert np.all(np.isinf(t[prim < 0]))


def _fixed_soup():
    """50 random triangles and 4000 rays, most aimed at their interiors: (corners, origins,
    directions, tfar)."""
    rng = np.random.default_rng(3)
    corners = rng.uniform(-1, 1, (50, 3, 3)).astype(np.float32)
    origins = rng.uniform(-2, 2, (4000, 3)).astype(np.float32)
    tri = rng.integers(0, 50, 4000)
    goal = np.einsum("rk,rkc->rc", rng.dirichlet([1, 1, 1], 4000), corners[tri])
    d = (goal - origins).astype(np.float32)
    return corners, origins, d, np.full(4000, np.inf, np.float32)


def test_embree_hits_are_common_in_the_property_test():
    """A fixed soup: most rays aimed at interiors hit, and every hit equals brute force."""
    corners, origins, d, tfar = _fixed_soup()
    t, prim, u, v = TriangleScene(corners).intersect(origins, d, tfar, threads=2)
    bt, bprim, bu, bv, ambiguous = brute_force(corners, origins, d, tfar.astype(np.float64))
    assert (bprim >= 0).mean() > 0.99
    assert ambiguous.mean() < 0.01
    clear = ~ambiguous
    np.testing.assert_array_equal(prim[clear], bprim[clear])
    np.testing.assert_allclose(t[clear], bt[clear], rtol=T_REL)


@compiled_only  # (with the JIT off embreex traces, robust whichever is asked)
def test_fast_scenes_find_the_brute_force_hits():
    """Scenes built with Mitsuba 3's settings (`fast`: no robust flag, high build quality:
    another tree, and hits worked with other rounding) find brute force's nearest hit
    wherever it is clear, within the same tolerance as the robust ones, on the same soup
    and rays."""
    corners, origins, d, tfar = _fixed_soup()
    scene = TriangleScene(corners, fast=True)
    library = embree._embree()
    assert library.scene_flags(scene.handle) == 0  # not robust: Mitsuba's
    assert library.scene_flags(TriangleScene(corners).handle) == embree._ROBUST
    t, prim, u, v = scene.intersect(origins, d, tfar, threads=2)
    bt, bprim, bu, bv, ambiguous = brute_force(corners, origins, d, tfar.astype(np.float64))
    assert (bprim >= 0).mean() > 0.99
    clear = ~ambiguous
    np.testing.assert_array_equal(prim[clear], bprim[clear])
    np.testing.assert_allclose(t[clear], bt[clear], rtol=T_REL)


def test_empty_scene_never_hits():
    t, prim, u, v = TriangleScene(np.zeros((0, 3, 3), np.float32)).intersect(
        np.zeros((3, 3), np.float32), np.ones((3, 3), np.float32), np.full(3, np.inf, np.float32))
    assert np.all(prim == -1) and np.all(np.isinf(t))


# ---------------------------------------------------------------- analytic spheres, cylinders

shapes = st.lists(
    st.tuples(
        st.sampled_from([SPHERE, CYLINDER, PLANAR, MESH]),
        arrays(np.float64, 3, elements=st.floats(-2, 2)),
        arrays(np.float64, 3, elements=st.floats(-1, 1)).filter(
            lambda a: np.linalg.norm(a) > 0.2),
        st.floats(0.1, 1.5), st.floats(0.1, 3.0),
    ),
    min_size=1, max_size=5,
)


def rectangle(center, normal, w, h):
    """Corners p00 p10 p11 p01 of a w x h rectangle facing `normal`, and its plane."""
    n = normal / np.linalg.norm(normal)
    helper = np.array([0.0, 1.0, 0.0]) if abs(n[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = np.cross(helper, n)
    e1 *= w / np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    e2 *= h / np.linalg.norm(e2)
    c00 = center - 0.5 * (e1 + e2)
    return n, float(-n @ c00), np.stack([c00, c00 + e1, c00 + e1 + e2, c00 + e2])


@settings(max_examples=300, deadline=None)
@given(shapes, st.integers(0, 2**32 - 1), st.sampled_from([0.0, 0.5]),
       st.sampled_from([np.inf, 4.0]))
def test_analytic_matches_closed_forms(shape_list, seed, tmin, far):
    rng = np.random.default_rng(seed)
    k = len(shape_list)
    kind = np.array([s[0] for s in shape_list], np.int32)
    params = np.zeros((k, MIRROR_PARAMS), np.float64)
    for i, (kd, c, a, r, h) in enumerate(shape_list):
        if kd == SPHERE:
            params[i, :4] = (*c, r)
        elif kd == CYLINDER:
            params[i, :8] = (*c, *(a / np.linalg.norm(a)), r, h)
        elif kd == PLANAR:
            n, dd, corners = rectangle(c, a, 2 * r, h)
            params[i, :16] = (*n, dd, *corners.reshape(-1))
        else:  # a mesh mirror row: Embree's business, the analytic intersector ignores it
            params[i, :3] = c
    n = 256
    origins = rng.uniform(-4, 4, (n, 3)).astype(np.float32)
    # aim at a random point near a random shape
    pick = rng.integers(0, k, n)
    goal = params[pick, :3] + rng.normal(0, 1.0, (n, 3))
    goal[kind[pick] == PLANAR] = params[pick, 4:7][kind[pick] == PLANAR] + rng.normal(
        0, 1.0, (int((kind[pick] == PLANAR).sum()), 3))
    d = (goal - origins) * rng.uniform(0.2, 2.0, (n, 1))
    d = d.astype(np.float32)
    d[np.linalg.norm(d, axis=1) < 1e-3] = (0, 0, 1)
    tfar = np.full(n, far, np.float32)
    t, idx = intersect_analytic(origins, d, tfar, kind, params, tmin)

    # the closed forms of every shape together, and where their own ambiguity (tangents,
    # rims, edges, near ties) allows either answer
    best, which, marginal = analytic_nearest(origins, d, tfar, kind, params, tmin)
    clear = ~marginal
    np.testing.assert_array_equal(idx[clear], which[clear])
    hit = clear & (which >= 0)
    np.testing.assert_allclose(t[hit], best[hit], rtol=1e-6)
    assert np.all(np.isinf(t[idx < 0]))
    assert not np.any(kind[idx[idx >= 0]] == MESH)


def test_analytic_property_cases_are_mostly_clear():
    """The exclusions of the property test leave almost every ray to compare."""
    rng = np.random.default_rng(11)
    kind = np.array([SPHERE, CYLINDER, SPHERE, CYLINDER], np.int32)
    params = np.zeros((4, MIRROR_PARAMS))
    params[:, :8] = [[0, 0, 0, 1, 0, 0, 0, 0], [2, -1, 0, 0.6, 0.8, 0, 0.5, 2],
                     [-1.5, 1, 1, 0.7, 0, 0, 0, 0], [0, 0, -2, 1, 0, 0, 0.3, 3]]
    n = 20000
    o = rng.uniform(-4, 4, (n, 3)).astype(np.float32)
    d = (params[rng.integers(0, 4, n), :3] + rng.normal(0, 1, (n, 3)) - o).astype(np.float32)
    t, idx = intersect_analytic(o, d, np.full(n, np.inf, np.float32), kind, params, 0.0)
    o64, d64, p = o.astype(float), d.astype(float), params.astype(float)
    cols, marginal = [], np.zeros(n, bool)
    for i in range(4):
        if kind[i] == SPHERE:
            ti, disc, _ = sphere_closed_form(o64, d64, p[i, :3], p[i, 3], 0.0)
            marginal |= (disc >= 0) & (disc < 1e-8 * p[i, 3] ** 2 / (d64 * d64).sum(1))
        else:
            ti, m = cylinder_closed_form(o64, d64, p[i, :3], p[i, 3:6], p[i, 6], p[i, 7], 0.0)
            marginal |= m
        cols.append(ti)
    all_t = np.stack(cols, 1)
    which = np.where(np.isfinite(all_t.min(1)), all_t.argmin(1), -1)
    assert marginal.mean() < 0.001
    assert (which >= 0).mean() > 0.4
    clear = ~marginal
    np.testing.assert_array_equal(idx[clear], which[clear])
    hit = clear & (which >= 0)
    np.testing.assert_allclose(t[hit], all_t.min(1)[hit], rtol=1e-6)


def test_analytic_sphere_and_tube_by_hand():
    """Rays along the axes meet a unit sphere and a unit tube where geometry says."""
    kind = np.array([SPHERE, CYLINDER], np.int32)
    params = np.zeros((2, MIRROR_PARAMS))
    params[:, :8] = [[0, 0, 0, 1, 0, 0, 0, 0], [10, 0, 0, 0, 1, 0, 1, 2]]
    o = np.array([[0, 0, 5], [0, 0, 0], [10, 1, 5], [10, 3, 5], [10, -5, 0.5]], np.float32)
    d = np.array([[0, 0, -1], [1, 0, 0], [0, 0, -2], [0, 0, -1], [0, 1, 0]], np.float32)
    t, idx = intersect_analytic(o, d, np.full(5, np.inf, np.float32), kind, params, 0.0)
    np.testing.assert_array_equal(idx, [0, 0, 1, -1, -1])
    np.testing.assert_allclose(t[:3], [4.0, 1.0, 2.0], rtol=1e-7)  # from inside: far root
    # the segment stops short: tfar below the hit leaves the ray unhit
    t, idx = intersect_analytic(o[:1], d[:1], np.array([3.9], np.float32), kind, params, 0.0)
    assert idx[0] == -1 and np.isinf(t[0])


@compiled_only
def test_embree_kernel_equals_embreex_bit_for_bit():
    """The kernel calling Embree's C API builds and queries as embreex does: same hits, same
    t, u, v to the bit, on any thread count (misses: inf, -1, 0, 0)."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    rng = np.random.default_rng(11)
    corners = rng.uniform(-1, 1, (300, 3, 3)).astype(np.float32)
    origins = rng.uniform(-2, 2, (20000, 3)).astype(np.float32)
    goal = rng.uniform(-1, 1, (20000, 3))
    d = (goal - origins).astype(np.float32)
    tfar = rng.choice([np.inf, 1.0, 3.0], 20000).astype(np.float32)
    scene = TriangleScene(corners)
    assert scene._handle, "the Embree library inside the embreex wheel was not found"
    ref = rtcore_scene.EmbreeScene()
    TriangleMesh(ref, corners)
    res = ref.run(origins, d, dists=tfar.copy(), output=1)
    hit = res["primID"] >= 0
    assert 0.2 < hit.mean() < 0.95
    for threads in (1, 2, 3):
        t, prim, u, v = scene.intersect(origins, d, tfar, threads=threads)
        np.testing.assert_array_equal(prim, res["primID"])
        np.testing.assert_array_equal(t, np.where(hit, res["tfar"], np.inf))
        np.testing.assert_array_equal(u[hit], res["u"][hit])
        np.testing.assert_array_equal(v[hit], res["v"][hit])
        assert (u[~hit] == 0).all() and (v[~hit] == 0).all()


def test_embreex_fallback_gives_the_same_hits(monkeypatch):
    """Without the library file the binding traces the rays: the same answers."""
    import reflectcli.trace.embree as embree

    rng = np.random.default_rng(5)
    corners = rng.uniform(-1, 1, (100, 3, 3)).astype(np.float32)
    origins = rng.uniform(-2, 2, (3000, 3)).astype(np.float32)
    d = (rng.uniform(-1, 1, (3000, 3)) - origins).astype(np.float32)
    tfar = np.full(3000, np.inf, np.float32)
    fast = TriangleScene(corners).intersect(origins, d, tfar, threads=2)
    monkeypatch.setattr(embree, "_embree", lambda: None)
    slow_scene = TriangleScene(corners)
    assert not slow_scene._handle
    slow = slow_scene.intersect(origins, d, tfar, threads=2)
    hit = slow[1] >= 0
    for a, b in zip(fast[:2], slow[:2], strict=True):
        np.testing.assert_array_equal(a, b)
    for a, b in zip(fast[2:], slow[2:], strict=True):
        np.testing.assert_array_equal(a[hit], b[hit])


def test_scene_released_when_dropped_even_after_module_teardown(monkeypatch):
    """A scene's Embree handle is released when the object goes, and still without an
    error once the module's globals are gone, as at interpreter exit (a __del__ then found
    `ctypes` None: "Exception ignored ... 'NoneType' object has no attribute
    'c_void_p'")."""
    import gc
    import sys

    import reflectcli.trace.embree as embree

    corners = np.random.default_rng(3).uniform(-1, 1, (20, 3, 3)).astype(np.float32)
    scene = TriangleScene(corners)
    release = scene._release
    assert release.alive
    del scene
    gc.collect()
    assert not release.alive
    raised = []
    monkeypatch.setattr(sys, "unraisablehook", raised.append)
    late = TriangleScene(corners)
    assert late.handle
    monkeypatch.setattr(embree, "ctypes", None)  # what shutdown does to module globals
    del late
    gc.collect()
    assert raised == []
