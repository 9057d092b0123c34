"""Shading of raster buffers: the viewpoint decides which side of a two-sided surface is lit."""

from __future__ import annotations

import numpy as np

from reflectcli.raster.rasterize import RasterBuffers
from reflectcli.raster.shade import shade_buffers
from reflectcli.scene.types import Triangles


class _Lit:
    """A lambert scene of one grey object lit by one directional light from above."""

    n_objects = 1
    shading = 1  # LAMBERT
    ambient = 0.1
    background = np.zeros(3, np.float32)

    # (float32 arrays, as a built scene holds them: the kernels compile once)
    class materials:  # noqa: N801
        mat_i = np.zeros((1, 5), np.int32)
        mat_f = np.array([[0.5, 0.5, 0.5, 0, 0, 0, 1, 1]], np.float32)
        texels = np.zeros((1, 3), np.float32)

    class lights:  # noqa: N801
        light_f = np.array([[1, 0.0, -1.0, 0.0, 1.0, 1.0, 1.0]], np.float32)  # directional

    class mirrors:  # noqa: N801
        reflectance = np.zeros((0, 3), np.float32)
        base = np.zeros((0, 3), np.float32)


def _naive(points, normals, dirs):
    """Two-sided lambert, one light travelling -y, albedo 0.5, ambient 0.1 (numpy)."""
    n = normals / np.linalg.norm(normals, axis=-1, keepdims=True)
    n = np.where((np.sum(n * dirs, axis=-1) > 0)[..., None], -n, n)
    return 0.5 * (0.1 + np.maximum(n[..., 1], 0.0))[..., None] * np.ones(3)


def test_incoming_rays_choose_the_lit_side():
    """A horizontal triangle, normal up, under a light from above: from above it is lit,
    seen along rays going up (from below, as a floor mirror shows it) it is not."""
    rng = np.random.default_rng(1)
    corners = np.array([[[-1, 0, -1], [1, 0, -1], [0, 0, 1]]], np.float32)
    normals = np.array([[[0.1, 1, 0], [0, 1, 0.2], [-0.1, 1, 0]]], np.float32)
    tris = Triangles(corners, np.zeros((1, 3, 2), np.float32), normals,
                     np.zeros(1, np.int32), np.zeros(1, np.int32))
    h, w = 4, 5
    b1 = rng.uniform(0, 0.5, (h, w)).astype(np.float32)
    b2 = rng.uniform(0, 0.5, (h, w)).astype(np.float32)
    buffers = RasterBuffers(np.zeros((h, w), np.int32), b1, b2, np.ones((h, w), np.float32))
    c0 = 1 - b1 - b2
    bary = np.stack([c0, b1, b2], -1).astype(np.float64)
    points = bary @ corners[0].astype(np.float64)
    nrm = bary @ normals[0].astype(np.float64)
    eye = np.array([0.0, 3.0, 0.5])
    from_eye, _ = shade_buffers(buffers, tris, _Lit, eye)
    same, _ = shade_buffers(buffers, tris, _Lit, eye, points - eye)
    assert np.array_equal(from_eye, same)
    np.testing.assert_allclose(from_eye, _naive(points, nrm, points - eye), rtol=1e-5)
    up = np.broadcast_to(np.array([0.3, 1.0, -0.2]), (h, w, 3))  # rays arriving from below
    below, _ = shade_buffers(buffers, tris, _Lit, eye, up)
    np.testing.assert_allclose(below, _naive(points, nrm, up), rtol=1e-5)
    assert (below < from_eye).all()
