"""Lengyel's oblique near plane: only the third row changes, the plane becomes NDC z = -1."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from reflectcli.camera import Camera
from reflectcli.geometry import far_plane_clip, oblique_projection

CAM = Camera(np.array([0.0, 0, 0]), np.array([0.0, 0, -1]), np.array([0.0, 1, 0]), 60.0,
             640, 480, 0.1, 100.0)
P = CAM.projection_matrix()


def _plane(tilt_x, tilt_y, dist):
    """An eye-space plane facing away from the eye (camera on its negative side)."""
    n = np.array([tilt_x, tilt_y, -1.0])
    n /= np.linalg.norm(n)
    return np.append(n, -dist)  # n . x - dist >= 0 is the kept side, beyond the plane


planes = st.tuples(st.floats(-0.6, 0.6), st.floats(-0.6, 0.6), st.floats(0.5, 20.0))


@settings(max_examples=60, deadline=None)
@given(planes)
def test_only_the_third_row_changes(p):
    o = oblique_projection(P, _plane(*p))
    np.testing.assert_array_equal(o[[0, 1, 3]], P[[0, 1, 3]])


@settings(max_examples=60, deadline=None)
@given(planes, st.floats(-0.5, 0.5), st.floats(-0.4, 0.4))
def test_plane_maps_to_near_and_order_is_kept(p, sx, sy):
    plane = _plane(*p)
    o = oblique_projection(P, plane)
    ray = np.array([sx, sy, -1.0])
    t_plane = -plane[3] / (plane[:3] @ ray)  # where the view ray meets the plane
    on = np.append(t_plane * ray, 1.0)
    c = o @ on
    assert abs(c[2] / c[3] + 1.0) < 1e-6
    # behind the plane (between eye and plane): clipped, z < -w
    behind = o @ np.append(0.5 * t_plane * ray, 1.0)
    assert behind[2] < -behind[3]
    # in front: NDC z grows with distance along the ray
    ts = t_plane * np.array([1.01, 1.5, 2.0, 4.0, 8.0])
    z = [(o @ np.append(t * ray, 1.0))[2] / (o @ np.append(t * ray, 1.0))[3] for t in ts]
    assert np.all(np.diff(z) > 0)


def test_standard_far_plane_as_clip_plane():
    o = oblique_projection(P, _plane(0.2, -0.1, 3.0))
    far = far_plane_clip(o, CAM.far)
    inside = o @ np.array([0.0, 0.0, -99.0, 1.0])
    outside = o @ np.array([0.0, 0.0, -101.0, 1.0])
    assert far @ inside > 0 > far @ outside
