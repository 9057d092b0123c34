"""Plane and reflection math against the formula x' = x - 2 (n.x + d) n, and Euler order."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from reflectcli.geometry import (
    euler_matrix,
    plane_from_points,
    reflect_point,
    reflect_vector,
    reflection_matrix,
    trs_matrix,
)

coord = st.floats(-100.0, 100.0, allow_nan=False, allow_infinity=False)
vec3 = arrays(np.float64, 3, elements=st.floats(-1.0, 1.0, allow_nan=False)).filter(
    lambda v: np.linalg.norm(v) > 0.1
)
points = arrays(np.float64, (5, 3), elements=coord)


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def apply(m: np.ndarray, x: np.ndarray) -> np.ndarray:
    h = np.concatenate([x, np.ones((len(x), 1))], axis=1) @ m.T
    return h[:, :3] / h[:, 3:]


@settings(max_examples=200, deadline=None)
@given(vec3, coord, points)
def test_reflection_matrix_is_the_formula(n, d, x):
    n = unit(n)
    expected = x - 2.0 * (x @ n + d)[:, None] * n
    m = reflection_matrix(n, d)
    scale = 1.0 + np.abs(x).max() + abs(d)
    np.testing.assert_allclose(apply(m, x), expected, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(reflect_point(x, n, d), expected, rtol=0, atol=1e-12 * scale)
    for row, want in zip(x, expected, strict=True):  # 1-D input path
        np.testing.assert_allclose(reflect_point(row, n, d), want, rtol=0, atol=1e-12 * scale)


@settings(max_examples=200, deadline=None)
@given(vec3, coord)
def test_reflection_is_an_involution_with_determinant_minus_one(n, d):
    n = unit(n)
    m = reflection_matrix(n, d)
    np.testing.assert_allclose(m @ m, np.eye(4), atol=1e-12 * (1 + abs(d)))
    assert np.linalg.det(m[:3, :3]) == pytest.approx(-1.0, abs=1e-12)
    assert np.linalg.det(m) == pytest.approx(-1.0, abs=1e-12)
    np.testing.assert_array_equal(m[3], [0, 0, 0, 1])
    # points on the plane are fixed; the normal flips
    p = -d * n
    np.testing.assert_allclose(apply(m, p[None])[0], p, atol=1e-12 * (1 + abs(d)))
    np.testing.assert_allclose(m[:3, :3] @ n, -n, atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(vec3, coord, points)
def test_reflect_vector_is_the_linear_part(n, d, v):
    n = unit(n)
    m = reflection_matrix(n, d)
    scale = 1.0 + np.abs(v).max()
    np.testing.assert_allclose(reflect_vector(v, n), v @ m[:3, :3].T, atol=1e-12 * scale)
    np.testing.assert_allclose(reflect_vector(v[0], n), m[:3, :3] @ v[0], atol=1e-12 * scale)
    # a vector is the difference of two points: reflect_point and reflect_vector agree
    a, b = v[0], v[1]
    np.testing.assert_allclose(
        reflect_point(b, n, d) - reflect_point(a, n, d), reflect_vector(b - a, n),
        atol=1e-10 * (scale + abs(d)),
    )
    # lengths are preserved and the component along n flips
    r = reflect_vector(v, n)
    np.testing.assert_allclose(np.linalg.norm(r, axis=1), np.linalg.norm(v, axis=1),
                               atol=1e-12 * scale)
    np.testing.assert_allclose(r @ n, -(v @ n), atol=1e-12 * scale)


def test_euler_order_is_rz_ry_rx():
    np.testing.assert_allclose(euler_matrix([90, 0, 0]) @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(euler_matrix([0, 90, 0]) @ [0, 0, 1], [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(euler_matrix([0, 0, 90]) @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    # x first, then y: +y -> +z (about x), then +z -> +x (about y)
    np.testing.assert_allclose(euler_matrix([90, 90, 0]) @ [0, 1, 0], [1, 0, 0], atol=1e-15)
    # z applied first (Rx @ Rz) would send +y to -x instead
    np.testing.assert_allclose(euler_matrix([90, 0, 90]) @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(euler_matrix([90, 0, 90]) @ [1, 0, 0], [0, 1, 0], atol=1e-15)


@settings(max_examples=100, deadline=None)
@given(arrays(np.float64, 3, elements=st.floats(-360, 360, allow_nan=False)))
def test_euler_composition_and_trs(angles):
    ax, ay, az = angles
    r = euler_matrix(angles)
    np.testing.assert_allclose(
        r, euler_matrix([0, 0, az]) @ euler_matrix([0, ay, 0]) @ euler_matrix([ax, 0, 0]),
        atol=1e-12,
    )
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-12)
    m = trs_matrix([1.0, -2.0, 3.0], angles, 2.0)
    np.testing.assert_allclose(m[:3, :3], 2.0 * r, atol=1e-12)
    np.testing.assert_allclose(m @ [0, 0, 0, 1], [1.0, -2.0, 3.0, 1.0])


@settings(max_examples=200, deadline=None)
@given(arrays(np.float64, (3, 3), elements=st.floats(-10, 10, allow_nan=False)))
def test_plane_from_points_orientation(p):
    e1, e2 = p[1] - p[0], p[2] - p[0]
    cross = np.cross(e1, e2)
    if np.linalg.norm(cross) < 1e-3:
        return
    n, d = plane_from_points(*p)
    assert np.linalg.norm(n) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(p @ n + d, 0.0, atol=1e-9)
    assert n @ cross > 0  # front side is (p1 - p0) x (p2 - p0)
    assert (p[0] + cross) @ n + d > 0
    # swapping two points flips the orientation
    n2, d2 = plane_from_points(p[0], p[2], p[1])
    np.testing.assert_allclose(n2, -n, atol=1e-12)
    assert d2 == pytest.approx(-d, abs=1e-9)


def test_plane_from_points_counter_clockwise_faces_viewer():
    n, d = plane_from_points([0, 0, 0], [1, 0, 0], [0, 1, 0])
    np.testing.assert_allclose(n, [0, 0, 1])
    assert d == 0.0
    n, d = plane_from_points([0, 2, 0], [0, 2, 1], [1, 2, 0])  # y = 2, front +y
    np.testing.assert_allclose(n, [0, 1, 0])
    assert d == pytest.approx(-2.0)
    with pytest.raises(ValueError):
        plane_from_points([0, 0, 0], [1, 1, 1], [2, 2, 2])
