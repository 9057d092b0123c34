"""The Bezier teapot: growth with subdivision, outward normals and winding, native z-up."""

from __future__ import annotations

import numpy as np
import pytest

from reflectcli.scene.teapot import teapot


def signed_volume(corners: np.ndarray) -> float:
    c = corners
    return float(np.einsum("ij,ij->i", c[:, 0], np.cross(c[:, 1], c[:, 2])).sum() / 6.0)


def test_triangle_count_grows():
    counts = [teapot(s).triangle_count for s in (2, 4, 8)]
    assert counts[0] < counts[1] < counts[2]
    assert counts[2] <= 32 * 2 * 8 * 8


@pytest.mark.parametrize("level", [3, 10])
def test_clean_triangles_and_unit_normals(level):
    m = teapot(level)
    assert m.areas().min() > 1e-12
    assert np.allclose(np.linalg.norm(m.normals, axis=2), 1.0)
    assert m.uvs.min() >= 0 and m.uvs.max() <= 1


def test_outward_winding_and_normals():
    m = teapot(12)
    assert signed_volume(m.corners) > 20.0  # roughly 25.9 for the closed-bottom teapot
    dots = np.einsum("fck,fk->fc", m.normals, m.face_normals())
    assert dots.min() > 0
    # on the body's widest band (away from handle and spout, |y| < 0.5 there), normals
    # point away from the z axis
    centre = m.corners.mean(axis=1)
    radius = np.hypot(centre[:, 0], centre[:, 1])
    band = (np.abs(centre[:, 2] - 1.2) < 0.2) & (radius > 1.8) & (np.abs(centre[:, 1]) > 0.6)
    assert band.sum() > 50
    radial = centre[band] * [1, 1, 0]
    assert np.all(np.einsum("fk,fk->f", m.face_normals()[band], radial) > 0)
    # the bottom faces down, the lid knob top faces up
    bottom = centre[:, 2] < 0.01
    assert bottom.any() and np.all(m.face_normals()[bottom][:, 2] < -0.9)
    top = centre[:, 2] > 3.14
    assert top.any() and np.all(m.face_normals()[top][:, 2] > 0.9)


def test_native_z_up_bounds():
    pts = teapot(8).corners.reshape(-1, 3)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    assert -3.1 < lo[0] < -2.9 and 3.3 < hi[0] < 3.5
    assert np.isclose(lo[2], 0.0, atol=1e-9) and 3.1 < hi[2] < 3.2
    assert np.isclose(lo[1], -2.0) and np.isclose(hi[1], 2.0)


def test_cached_and_frozen():
    a, b = teapot(5), teapot(5)
    assert a is b
    with pytest.raises(ValueError):
        a.corners[0, 0, 0] = 1.0
    with pytest.raises(ValueError):
        teapot(0)


@pytest.mark.parametrize("level", [5, 8])
def test_patch_seams_are_welded(level):
    """Neighbouring patches meet at bit-identical vertices (else rays slip between them):
    no two distinct vertices closer than 1e-6, and the only open edges are Newell's own
    (the lid's gap at z = 2.4, the spout's mouth, handle and spout ends)."""
    from scipy.spatial import cKDTree

    m = teapot(level)
    pts, inverse = np.unique(m.corners.reshape(-1, 3), axis=0, return_inverse=True)
    assert len(cKDTree(pts).query_pairs(1e-6)) == 0
    tri = inverse.reshape(-1, 3)
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    unique, count = np.unique(edges, axis=0, return_counts=True)
    assert count.max() == 2
    open_points = pts[np.unique(unique[count == 1])]
    on_lid_gap = np.isclose(open_points[:, 2], 2.4)
    radius = np.hypot(open_points[:, 0], open_points[:, 1])
    assert np.isclose(radius[on_lid_gap], 1.3, atol=0.01).sum() == 4 * level  # lid's rim
    assert np.isclose(radius[on_lid_gap], 1.4, atol=0.01).sum() == 4 * level  # body's rim
    # the rest: spout mouth and the handle's and spout's ends, all away from the lid
    assert (~on_lid_gap).sum() <= 8 * level + 8


@pytest.mark.parametrize("level", [1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 64])
def test_grid_weld_equals_kd_tree_weld(level):
    """The seam weld (a 1e-7 grid, numpy only: validate stays fast) groups exactly the
    points a KD-tree groups within 1e-9 (its twin in tests/naive.py), at every size."""
    from naive import weld_within

    from reflectcli.scene.teapot import patch_points, weld_points

    raw = patch_points(level)
    np.testing.assert_array_equal(weld_points(raw), weld_within(raw))
