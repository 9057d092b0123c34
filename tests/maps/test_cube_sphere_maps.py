"""Map lookups: texel centers round-trip through the lookup; the sphere map's (s, t)."""

from __future__ import annotations

import numpy as np
import pytest

from reflectcli.maps.cube import cube_face_coords, face_bases, face_camera, lookup_cube
from reflectcli.maps.sphere import sphere_coords, sphere_from_cube


@pytest.mark.parametrize("face", range(6))
def test_cube_texel_centers_round_trip(face):
    res = 16
    cam = face_camera(face, np.array([1.0, -2.0, 0.5]), res, 0.1, 10.0)
    dirs = cam.pixel_directions(1)[:, :, 0]  # (H, W, 3), the face camera's pixel centers
    bases = face_bases()
    for j in range(res):
        for i in range(res):
            f, u, v = cube_face_coords(bases, *dirs[j, i])
            assert f == face
            assert abs(u * res - (i + 0.5)) < 1e-9 and abs(v * res - (j + 0.5)) < 1e-9


def test_cube_lookup_nearest_returns_the_texel():
    res = 8
    faces = np.random.default_rng(0).random((6, res, res, 3)).astype(np.float32)
    for face in range(6):
        cam = face_camera(face, np.zeros(3), res, 0.1, 10.0)
        dirs = cam.pixel_directions(1)[:, :, 0].reshape(-1, 3)
        got = lookup_cube(faces, dirs, bilinear=False).reshape(res, res, 3)
        np.testing.assert_array_equal(got, faces[face])
        # bilinear at texel centers is the texel itself
        got = lookup_cube(faces, dirs, bilinear=True).reshape(res, res, 3)
        np.testing.assert_allclose(got, faces[face], atol=1e-6)


def test_sphere_map_coordinates_follow_the_notes():
    # r = 2 (n.v) n - v for n = (s, t, sqrt(1 - s^2 - t^2)), v = (0, 0, 1) maps back to (s, t)
    rng = np.random.default_rng(1)
    for _ in range(200):
        s, t = rng.uniform(-0.99, 0.99, 2)
        if s * s + t * t >= 0.98:
            continue
        n = np.array([s, t, np.sqrt(1 - s * s - t * t)])
        r = 2 * n[2] * n - np.array([0, 0, 1.0])
        u, v = sphere_coords(*r)
        assert abs(u - (s + 1) / 2) < 1e-9 and abs(v - (1 - t) / 2) < 1e-9
    # the map's center looks back at the viewer, its rim straight away
    assert sphere_coords(0.0, 0.0, 1.0) == (0.5, 0.5)


def test_sphere_map_from_cube_matches_cube_lookup():
    res = 32
    rng = np.random.default_rng(2)
    faces = np.repeat(np.repeat(rng.random((6, 4, 4, 3)), 8, 1), 8, 2).astype(np.float32)
    disk = sphere_from_cube(faces, 64)
    j, i = 20, 40
    s, t = 2 * (i + 0.5) / 64 - 1, 1 - 2 * (j + 0.5) / 64
    n = np.array([s, t, np.sqrt(1 - s * s - t * t)])
    r = 2 * n[2] * n - np.array([0, 0, 1.0])
    np.testing.assert_allclose(disk[j, i], lookup_cube(faces, r[None], True)[0], atol=1e-6)
    assert res and disk[0, 0].sum() == 0  # outside the disk stays black
