"""Geometry contracts of the primitives: orientation, UV layout, normals, closed volumes."""

from __future__ import annotations

import numpy as np
import pytest

from reflectcli.scene.mesh import Mesh
from reflectcli.scene.primitives import (
    box,
    cone,
    cylinder,
    ico_sphere,
    pyramid,
    quad,
    room,
    torus,
    uv_sphere,
)

LO, HI = np.array([-2.0, 0.0, -3.0]), np.array([4.0, 2.5, 1.0])


def signed_volume(mesh: Mesh) -> float:
    c = mesh.corners
    return float(np.einsum("ij,ij->i", c[:, 0], np.cross(c[:, 1], c[:, 2])).sum() / 6.0)


def assert_normals_sane(mesh: Mesh, min_dot: float = 0.0) -> None:
    assert np.allclose(np.linalg.norm(mesh.normals, axis=2), 1.0)
    dots = np.einsum("fck,fk->fc", mesh.normals, mesh.face_normals())
    assert dots.min() > min_dot
    assert mesh.areas().min() > 0


def centroids(mesh: Mesh) -> np.ndarray:
    return mesh.corners.mean(axis=1)


def interpolate_uv(face_corners: np.ndarray, face_uvs: np.ndarray, point: np.ndarray):
    """UV at `point` inside the triangle, by barycentric weights."""
    a, b, c = face_corners
    m = np.stack([b - a, c - a], axis=1)
    w, *_ = np.linalg.lstsq(m, point - a, rcond=None)
    return (1 - w.sum()) * face_uvs[0] + w[0] * face_uvs[1] + w[1] * face_uvs[2]


def test_quad_front_and_default_uv():
    m = quad([[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]])
    assert m.triangle_count == 2
    assert np.allclose(m.face_normals(), [0, 0, 1])
    assert np.allclose(m.normals, [0, 0, 1])
    assert np.isclose(m.areas().sum(), 2.0)
    # corner p11 = (2, 1, 0) has uv (1, 1)
    hits = np.all(np.isclose(m.corners, [2, 1, 0]), axis=2)
    assert np.allclose(m.uvs[hits], [1, 1])


def test_box_faces_outward_and_exact_volume():
    m = box(LO, HI)
    assert m.triangle_count == 12
    assert_normals_sane(m, min_dot=0.999)
    centre = 0.5 * (LO + HI)
    assert np.all(np.einsum("fk,fk->f", m.face_normals(), centroids(m) - centre) > 0)
    assert np.isclose(signed_volume(m), np.prod(HI - LO))
    assert m.uvs.min() == 0.0 and m.uvs.max() == 1.0


def test_room_faces_inward():
    m = room(LO, HI)
    assert m.triangle_count == 12
    assert_normals_sane(m, min_dot=0.999)
    centre = 0.5 * (LO + HI)
    assert np.all(np.einsum("fk,fk->f", m.face_normals(), centre - centroids(m)) > 0)
    assert np.isclose(signed_volume(m), -np.prod(HI - LO))
    assert m.uvs.min() == 0.0 and m.uvs.max() == 1.0


def face_of(m: Mesh, normal) -> tuple[np.ndarray, np.ndarray]:
    pick = np.all(np.isclose(m.face_normals(), normal), axis=1)
    assert pick.sum() == 2
    return m.corners[pick], m.uvs[pick]


def uv_at(m: Mesh, normal, point) -> np.ndarray:
    corners, uvs = face_of(m, normal)
    point = np.asarray(point, dtype=np.float64)
    for c, t in zip(corners, uvs, strict=True):
        hit = np.all(np.isclose(c, point), axis=1)
        if hit.any():
            return t[hit][0]
    # interior point: the triangle whose barycentrics are all non-negative
    for c, t in zip(corners, uvs, strict=True):
        uv = interpolate_uv(c, t, point)
        a, b, cc = c
        w = np.linalg.lstsq(np.stack([b - a, cc - a], 1), point - a, rcond=None)[0]
        if w.min() >= -1e-9 and w.sum() <= 1 + 1e-9:
            return uv
    raise AssertionError(f"{point} not on face {normal}")


def test_room_uv_contract():
    m = room(LO, HI)
    (x0, y0, z0), (x1, y1, z1) = LO, HI
    # floor (normal +y): u = +x, v = -z
    assert np.allclose(uv_at(m, [0, 1, 0], [x0, y0, z1]), [0, 0])
    assert np.allclose(uv_at(m, [0, 1, 0], [x1, y0, z0]), [1, 1])
    # ceiling (normal -y): u = +x, v = +z
    assert np.allclose(uv_at(m, [0, -1, 0], [x0, y1, z0]), [0, 0])
    assert np.allclose(uv_at(m, [0, -1, 0], [x1, y1, z1]), [1, 1])
    # north wall (-z, normal +z), seen from inside: u grows with +x, v with +y
    assert np.allclose(uv_at(m, [0, 0, 1], [x0, y0, z0]), [0, 0])
    assert np.allclose(uv_at(m, [0, 0, 1], [x1, y1, z0]), [1, 1])
    assert np.allclose(uv_at(m, [0, 0, 1], [x0 + 1.5, y0 + 0.5, z0]), [0.25, 0.2])
    # south wall (+z): viewer faces +z, right is -x
    assert np.allclose(uv_at(m, [0, 0, -1], [x1, y0, z1]), [0, 0])
    assert np.allclose(uv_at(m, [0, 0, -1], [x0, y1, z1]), [1, 1])
    # west wall (-x): viewer faces -x, right is -z
    assert np.allclose(uv_at(m, [1, 0, 0], [x0, y0, z1]), [0, 0])
    assert np.allclose(uv_at(m, [1, 0, 0], [x0, y1, z0]), [1, 1])
    # east wall (+x): viewer faces +x, right is +z
    assert np.allclose(uv_at(m, [-1, 0, 0], [x1, y0, z0]), [0, 0])
    assert np.allclose(uv_at(m, [-1, 0, 0], [x1, y1, z1]), [1, 1])


def test_room_wall_uv_right_handed_from_inside():
    """On every wall, d(position)/du points to the right of a viewer facing the wall."""
    m = room(LO, HI, faces=["north", "south", "west", "east"])
    up = np.array([0.0, 1.0, 0.0])
    for corners, uvs, n in zip(m.corners, m.uvs, m.face_normals(), strict=True):
        edges = np.stack([corners[1] - corners[0], corners[2] - corners[0]])
        duv = np.stack([uvs[1] - uvs[0], uvs[2] - uvs[0]])
        dpdu, dpdv = np.linalg.solve(duv, edges)
        forward = -n  # the viewer looks at the wall, against its inward normal
        right = np.cross(forward, up)
        assert np.dot(dpdu, right) > 0
        assert np.dot(dpdv, up) > 0


def test_room_faces_subset():
    m = room(LO, HI, faces=["floor", "north"])
    assert m.triangle_count == 4
    normals = {tuple(np.round(n).astype(int)) for n in m.face_normals()}
    assert normals == {(0, 1, 0), (0, 0, 1)}
    with pytest.raises(ValueError):
        room(LO, HI, faces=["attic"])


@pytest.mark.parametrize("radius", [0.5, 2.0])
def test_uv_sphere(radius):
    m = uv_sphere(radius, 64)
    assert np.allclose(np.linalg.norm(m.corners, axis=2), radius)
    assert_normals_sane(m)
    assert np.allclose(m.normals * radius, m.corners)
    assert np.isclose(signed_volume(m), 4 / 3 * np.pi * radius**3, rtol=0.02)
    assert m.uvs.min() >= 0 and m.uvs.max() <= 1
    # no triangle straddles the u seam
    assert np.ptp(m.uvs[..., 0], axis=1).max() < 2.0 / 64
    # v = 0 at the south pole, 1 at the north pole; u = 0.25 toward -z
    v_expected = 0.5 + np.arcsin(np.clip(m.corners[..., 1] / radius, -1, 1)) / np.pi
    assert np.allclose(m.uvs[..., 1], v_expected)
    at_minus_z = np.all(np.isclose(m.corners, [0, 0, -radius]), axis=2)
    assert np.allclose(m.uvs[at_minus_z][:, 0], 0.25)


def test_ico_sphere():
    m = ico_sphere(1.5, 4)
    assert m.triangle_count == 20 * 4**4
    assert np.allclose(np.linalg.norm(m.corners, axis=2), 1.5)
    assert_normals_sane(m)
    assert np.isclose(signed_volume(m), 4 / 3 * np.pi * 1.5**3, rtol=0.02)
    assert np.ptp(m.uvs[..., 0], axis=1).max() < 0.5
    assert m.uvs[..., 0].min() >= 0 and m.uvs[..., 0].max() < 1.1
    assert m.uvs[..., 1].min() >= 0 and m.uvs[..., 1].max() <= 1


def test_cylinder():
    m = cylinder(0.5, 2.0, 128)
    assert_normals_sane(m)
    assert np.isclose(signed_volume(m), np.pi * 0.25 * 2.0, rtol=0.01)
    pts = m.corners.reshape(-1, 3)
    assert np.isclose(pts[:, 1].min(), 0) and np.isclose(pts[:, 1].max(), 2.0)
    assert m.uvs.min() >= 0 and m.uvs.max() <= 1
    side = np.abs(m.face_normals()[:, 1]) < 0.5
    assert np.allclose(m.uvs[side][..., 1], m.corners[side][..., 1] / 2.0)
    assert np.allclose(m.normals[side][..., 1], 0)
    open_tube = cylinder(0.5, 2.0, 16, caps=False)
    assert open_tube.triangle_count == 32


def test_cone_and_pyramid_volumes():
    c = cone(1.0, 3.0, 256)
    assert_normals_sane(c)
    assert np.isclose(signed_volume(c), np.pi / 3 * 3.0, rtol=0.01)
    apex = np.isclose(c.corners[..., 1], 3.0)
    assert np.allclose(c.uvs[apex][:, 1], 1.0)
    p = pyramid(2.0, 1.5)
    assert p.triangle_count == 6
    assert_normals_sane(p, min_dot=0.999)
    assert np.isclose(signed_volume(p), 4.0 * 1.5 / 3)
    apex = np.isclose(p.corners[..., 1], 1.5)
    assert np.allclose(p.uvs[apex], [0.5, 1.0])
    # inverted pyramid: a 180 degree rotation about x keeps it closed and outward
    flip = np.diag([1.0, -1.0, -1.0, 1.0])
    assert np.isclose(signed_volume(p.transformed(flip)), 4.0 * 1.5 / 3)


def test_torus():
    big, small = 2.0, 0.5
    m = torus(big, small, 96, 48)
    assert m.triangle_count == 2 * 96 * 48
    assert_normals_sane(m)
    assert np.isclose(signed_volume(m), 2 * np.pi**2 * big * small**2, rtol=0.01)
    ring = np.hypot(m.corners[..., 0], m.corners[..., 2])
    assert np.allclose(np.hypot(ring - big, m.corners[..., 1]), small)
    assert m.uvs.min() >= 0 and m.uvs.max() <= 1
