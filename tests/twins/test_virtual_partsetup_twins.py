"""A reflector's parts set up all at once (virtual/partsetup.py) against each part's own
calls (ray_foci, ExplosionPart's extent and screen positions, map_setup), bit for bit:
those are held to their numpy twins in test_virtual_explosion_twins.py."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from naive import lookup_axis as naive_lookup_axis
from naive import map_frame as naive_map_frame

from reflectcli.scene import primitives
from reflectcli.virtual import explosion, partsetup
from reflectcli.virtual.explosion import boundary_edges
from reflectcli.virtual.mesh import IndexedMesh, weld
from reflectcli.virtual.part import _extent, _lookup_axis
from reflectcli.virtual.screen import screen_from_world
from reflectcli.virtual.shape import join_parts


@pytest.fixture(scope="module")
def parts():
    """(meshes, boundaries, eyes, clip_from_world): the mask's 14 parts, two spheres, a
    sphere whose normals all turn from the first eye (no front vertex: the vertex mean)
    and a one-vertex part (a face welded to a point: projected alone, a row is projected
    by another route); the mask's eye and six around."""
    from conftest import open_scene

    rng = np.random.default_rng(11)
    opened = open_scene("mask", "virtual", ["camera.width=64", "camera.height=64"])
    state = opened.prepare()
    camera = opened.camera(0)
    meshes = [part.mesh for shape in state.shapes.entries.values() for part in shape.parts]
    meshes += [weld(m.corners, m.normals) for m in (primitives.uv_sphere(1.0, 12),
                                                   primitives.uv_sphere(0.7, 24))]
    away = meshes[-2].vertices - camera.eye
    away /= np.linalg.norm(away, axis=1, keepdims=True)
    meshes.append(dataclasses.replace(meshes[-2], normals=away))
    # (a point whose projection alone differs in its last bit from the same row's among
    # others, with the mask's camera)
    point = np.array([[1.3458754237823045, 2.1813114007004275, 0.2644556303293035]])
    meshes.append(IndexedMesh(point, np.array([[0.0, 0.0, 1.0]]),
                              np.zeros((1, 3), np.int64), np.zeros(1, np.int64)))
    boundaries = [boundary_edges(m.faces) for m in meshes]
    eyes = [np.asarray(camera.eye, np.float64)] + [rng.normal(0.0, 3.0, 3) for _ in range(6)]
    return meshes, boundaries, eyes, camera


def _choices(count: int):
    """Every part in order (the joined screen positions), and subsets out of order."""
    rng = np.random.default_rng(5)
    yield np.arange(count - 1)  # all but the one-vertex part: one projection for all
    yield np.arange(count)
    for _ in range(3):
        yield rng.permutation(count)[:rng.integers(1, count)]


def test_parts_foci_are_ray_foci(parts):
    meshes, boundaries, eyes, _ = parts
    joined = join_parts(meshes, boundaries)
    for chosen in _choices(len(meshes)):
        subset = [meshes[p] for p in chosen]
        for eye in eyes:
            got = partsetup.parts_foci(joined, chosen, subset, eye)
            want = explosion.ray_foci(subset, eye)
            assert [g.tobytes() for g in got] == [w.tobytes() for w in want]
            # the sums themselves, front counts included
            a, b = np.empty((len(chosen), 3, 3)), np.empty((len(chosen), 3))
            front = np.empty(len(chosen), np.int64)
            partsetup._focus_sums_parts(joined.vertices, joined.normals, joined.vstart,
                                        np.asarray(chosen, np.int64), np.asarray(eye), a, b,
                                        front)
            for j, mesh in enumerate(subset):
                aj, bj, count = explosion._focus_sums(mesh.vertices, mesh.normals,
                                                      np.asarray(eye))
                assert (a[j].tobytes(), b[j].tobytes(), front[j]) == (aj.tobytes(),
                                                                      bj.tobytes(), count)


def test_parts_extents_are_each_part_s(parts):
    """(bound, far, front, screen, flip) of each chosen part: part._extent's,
    screen_from_world's and ExplosionPart's lookup axis for the part alone, whether the
    parts are projected together (every part, none of one vertex) or one by one."""
    meshes, boundaries, eyes, camera = parts
    m = camera.clip_from_world()
    joined = join_parts(meshes, boundaries)
    scene_points = np.random.default_rng(2).normal(0.0, 4.0, (300, 3))
    concave = np.arange(len(meshes)) % 2 == 0  # every other part, whatever its shape
    for chosen in _choices(len(meshes)):
        for eye in eyes[:3]:
            centres = np.array([meshes[p].vertices.mean(axis=0) + 0.1 for p in chosen])
            got = partsetup.parts_extents(joined, chosen, centres, concave[chosen],
                                          scene_points, eye, m, camera.width, camera.height)
            assert len(got) == len(chosen)
            for (bound, far, front, screen, flip), p, centre in zip(got, chosen, centres,
                                                                    strict=True):
                mesh = meshes[p]
                want_front = np.empty(len(mesh.vertices), np.bool_)
                want = _extent(mesh.vertices, mesh.normals, centre, scene_points, eye,
                               want_front)
                assert (bound, far) == want
                assert front.tobytes() == want_front.tobytes()
                alone = screen_from_world(mesh.vertices, m, camera.width, camera.height)
                assert screen.shape == (len(mesh.vertices), 2)
                assert screen.tobytes() == alone[:, :2].tobytes()
                # ExplosionPart's lookup axis, as it makes it alone
                want_flip = np.zeros(3)
                if concave[p]:
                    _lookup_axis(mesh.normals, want_front, want_flip)
                assert flip.tobytes() == want_flip.tobytes()


def test_parts_map_setups_are_each_part_s(parts):
    """Every MapSetup field of each chosen part as map_setup gives it alone, and the
    joined arrays (v, fixed, used, faces, drawn, extensions) as build_maps_together joins
    the setups."""
    meshes, boundaries, eyes, _ = parts
    joined = join_parts(meshes, boundaries)
    rng = np.random.default_rng(8)
    for chosen in _choices(len(meshes)):
        subset = [meshes[p] for p in chosen]
        for eye in eyes[:3]:
            centres = [mesh.vertices.mean(axis=0) + rng.normal(0.0, 0.1, 3) for mesh in subset]
            radii = [explosion.layer_radii(1.0 + j, 20.0 + j, 4) for j in range(len(chosen))]
            lookups = [rng.normal(0.0, 1.0, (j + 1, 3)) if j % 3 else None
                       for j in range(len(chosen))]
            flips = [None if j % 2 else rng.normal(0.0, 1.0, 3) for j in range(len(chosen))]
            setups, arrays = partsetup.parts_map_setups(joined, chosen, subset, eye, centres,
                                                        radii, 32, lookups, flips)
            for j, p in enumerate(chosen):
                want = explosion.map_setup(meshes[p], eye, centres[j], 1.0, 20.0, 32, 4,
                                           boundaries[p], lookups[j], flips[j], radii[j])
                got = setups[j]
                assert got.mesh is meshes[p] and got.res == want.res and got.s == want.s
                for field in ("eye", "fixed", "front", "used", "drawn", "extensions", "frame",
                              "center", "radii", "lookups", "flip"):
                    g, w = getattr(got, field), getattr(want, field)
                    if w is None:
                        assert g is None
                        continue
                    assert g.dtype == w.dtype and g.shape == w.shape, field
                    assert g.tobytes() == w.tobytes(), field
            want_arrays = (np.concatenate([m.vertices for m in subset]),
                           np.concatenate([u.fixed for u in setups]),
                           np.concatenate([u.used for u in setups]),
                           np.concatenate([m.faces for m in subset]),
                           np.concatenate([u.drawn for u in setups]),
                           np.concatenate([u.extensions for u in setups]))
            for g, w in zip(arrays, want_arrays, strict=True):
                assert g.dtype == w.dtype and g.tobytes() == w.tobytes()


def _numpy_norm_is_an_fma_chain() -> bool:
    """Whether this machine's np.linalg.norm of a 3-vector is sqrt(fma(x2, x2, fma(x1, x1,
    x0 x0))) (OpenBLAS's ddot on this machine kind): the order _map_frames reproduces.
    Elsewhere it matches numpy to rounding only."""
    from fractions import Fraction

    rng = np.random.default_rng(4)
    for x in rng.normal(0.0, 3.0, (500, 3)):
        inner = float(Fraction(x[1]) * Fraction(x[1]) + Fraction(x[0] * x[0]))
        chain = float(Fraction(x[2]) * Fraction(x[2]) + Fraction(inner))
        if np.linalg.norm(x) != np.sqrt(chain):
            return False
    return True


def test_map_frames_are_map_frame():
    """The map frames' kernel (_map_frames, map_frame's for one centre) against its numpy
    twin, bit for bit where numpy's norm is the kernel's fused chain: random centres,
    directions whose y is near the 0.9 where the helper axis changes, far and near
    centres."""
    rng = np.random.default_rng(9)
    eye = np.array([0.2, 1.7, 3.1])
    directions = rng.normal(0.0, 1.0, (4000, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    tilt = rng.uniform(0.88, 0.92, 1000)
    directions[:1000, 1] = tilt * np.sign(rng.normal(size=1000))
    centres = eye - directions * rng.uniform(1e-3, 1e3, (4000, 1))
    frames = np.empty((len(centres), 3, 3))
    explosion._map_frames(centres, eye, frames)
    alone = np.array([explosion.map_frame(c, eye) for c in centres])
    assert frames.tobytes() == alone.tobytes()
    want = np.array([naive_map_frame(c, eye) for c in centres])
    if _numpy_norm_is_an_fma_chain():
        assert frames.tobytes() == want.tobytes()
    else:
        np.testing.assert_allclose(frames, want, rtol=1e-14, atol=1e-15)


def test_lookup_axis_matches_twin():
    """A concave part's lookup axis (part._lookup_axis: its front vertices' mean normal
    made unit) against its numpy twin, bit for bit where numpy's norm is the kernel's
    fused chain: random normals and fronts, none in front (0), one, all, a mean of zero
    length (the 1e-30 floor) and NaN normals."""
    rng = np.random.default_rng(13)
    bits = _numpy_norm_is_an_fma_chain()
    cases = []
    for _ in range(2000):
        k = int(rng.integers(1, 300))
        normals = rng.normal(0.0, 1.0, (k, 3)) * rng.uniform(1e-3, 1e3, (k, 1))
        cases.append((normals, rng.random(k) < rng.uniform(0.0, 1.0)))
    opposed = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    cases += [(opposed, np.ones(2, bool)), (opposed, np.zeros(2, bool)),
              (np.array([[np.nan, 0.0, 1.0], [0.0, 1.0, 0.0]]), np.ones(2, bool))]
    for normals, front in cases:
        got = np.empty(3)
        _lookup_axis(normals, front, got)
        want = naive_lookup_axis(normals, front)
        if bits:
            assert got.tobytes() == want.tobytes()
        else:
            np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-300)
