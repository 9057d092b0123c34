"""Camera model: look-at, OpenGL projection, pixel rays and camera paths."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from reflectcli.camera import Camera, camera_from_config, catmull_rom, linear
from reflectcli.config.camera import CameraConfig

pos = arrays(np.float64, 3, elements=st.floats(-20.0, 20.0, allow_nan=False))
direction = arrays(np.float64, 3, elements=st.floats(-1.0, 1.0, allow_nan=False))


def make_camera(eye, target, up=(0.0, 1.0, 0.0), fov=55.0, w=64, h=48, near=0.05, far=80.0):
    return Camera(np.asarray(eye, float), np.asarray(target, float), np.asarray(up, float),
                  fov, w, h, near, far)


def hom(x: np.ndarray) -> np.ndarray:
    return np.concatenate([x, np.ones(x.shape[:-1] + (1,))], axis=-1)


def to_screen(cam: Camera, world: np.ndarray) -> np.ndarray:
    """World points (..., 3) -> screen (x, y, ndc z), x right, y down, pixels."""
    clip = hom(world) @ (cam.projection_matrix() @ cam.view_matrix()).T
    ndc = clip[..., :3] / clip[..., 3:]
    return np.stack([(ndc[..., 0] + 1) * 0.5 * cam.width, (1 - ndc[..., 1]) * 0.5 * cam.height,
                     ndc[..., 2]], axis=-1)


cameras = st.builds(
    make_camera, pos, pos, direction.filter(lambda u: np.linalg.norm(u) > 0.2),
    st.floats(10.0, 120.0), st.integers(1, 50), st.integers(1, 50),
    st.floats(0.01, 1.0), st.floats(5.0, 200.0),
)


def valid(cam: Camera) -> bool:
    view = cam.target - cam.eye
    if np.linalg.norm(view) < 0.1:
        return False
    s = np.linalg.norm(np.cross(cam.up, view)) / (np.linalg.norm(cam.up) * np.linalg.norm(view))
    return s > 0.1  # up is not (nearly) parallel to the view direction


@settings(max_examples=200, deadline=None)
@given(cameras)
def test_look_at(cam):
    assume(valid(cam))
    v = cam.view_matrix()
    np.testing.assert_allclose(v @ hom(cam.eye), [0, 0, 0, 1], atol=1e-12 * (1 + 20))
    dist = np.linalg.norm(cam.target - cam.eye)
    np.testing.assert_allclose(v @ hom(cam.target), [0, 0, -dist, 1], atol=1e-10)
    r = v[:3, :3]
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_array_equal(v[3], [0, 0, 0, 1])
    # world up lies in the eye-space yz plane, on the +y side
    assert (r @ cam.up)[1] > 0
    assert abs((r @ cam.up)[0]) < 1e-12 * (1 + np.linalg.norm(cam.up))


@settings(max_examples=200, deadline=None)
@given(cameras, st.floats(-1, 1), st.floats(-1, 1))
def test_projection_near_and_far_planes(cam, a, b):
    assume(valid(cam))
    right, up, back = cam.basis()
    t = np.tan(np.radians(cam.fov_y) / 2)
    for depth, want in ((cam.near, -1.0), (cam.far, 1.0)):
        # a point anywhere in the frustum's cross-section at that eye-space depth
        p = cam.eye + depth * (-back + a * t * cam.aspect * right + b * t * up)
        s = to_screen(cam, p)
        assert s[2] == pytest.approx(want, abs=1e-9 * cam.far / cam.near)
        assert s[0] == pytest.approx((a + 1) * 0.5 * cam.width, abs=1e-7 * cam.width)
        assert s[1] == pytest.approx((1 - b) * 0.5 * cam.height, abs=1e-7 * cam.height)
    # clip w is the eye-space depth
    p = cam.eye - 3.0 * back
    clip = cam.projection_matrix() @ cam.view_matrix() @ hom(p)
    assert clip[3] == pytest.approx(3.0, rel=1e-9)


@settings(max_examples=200, deadline=None)
@given(cameras, arrays(np.float64, (8, 3), elements=st.floats(-1, 1, allow_nan=False)))
def test_project_unproject_round_trip(cam, u):
    assume(valid(cam))
    right, up, back = cam.basis()
    t = np.tan(np.radians(cam.fov_y) / 2)
    depth = cam.near + (u[:, 2] + 1) / 2 * (cam.far - cam.near)
    world = cam.eye + depth[:, None] * (-back + u[:, :1] * t * cam.aspect * right
                                        + u[:, 1:2] * t * up)
    m = cam.projection_matrix() @ cam.view_matrix()
    clip = hom(world) @ m.T
    ndc = clip[:, :3] / clip[:, 3:]
    assert np.all(np.abs(ndc) <= 1 + 1e-9)
    back_h = hom(ndc) @ np.linalg.inv(m).T
    np.testing.assert_allclose(back_h[:, :3] / back_h[:, 3:], world,
                               rtol=1e-6, atol=1e-6 * (1 + cam.far))


@settings(max_examples=100, deadline=None)
@given(cameras)
def test_pixel_directions_pass_pixel_centers(cam):
    assume(valid(cam))
    d = cam.pixel_directions(1)
    assert d.shape == (cam.height, cam.width, 1, 3)
    d = d[:, :, 0]
    # eye-space z of every direction is -1, so t along it is eye-space depth
    eye_space = d @ cam.view_matrix()[:3, :3].T
    np.testing.assert_allclose(eye_space[..., 2], -1.0, atol=1e-12)
    s = to_screen(cam, cam.eye + 2.0 * d)
    j, i = np.mgrid[0:cam.height, 0:cam.width]
    np.testing.assert_allclose(s[..., 0], i + 0.5, atol=1e-9 * cam.width)
    np.testing.assert_allclose(s[..., 1], j + 0.5, atol=1e-9 * cam.height)


def test_row_zero_is_the_top_and_column_zero_the_left():
    cam = make_camera([0, 0, 0], [0, 0, -1], w=4, h=3)
    d = cam.pixel_directions(1)[:, :, 0]
    assert d[0, 0, 1] > 0 and d[-1, 0, 1] < 0  # up at the top row
    assert d[0, 0, 0] < 0 and d[0, -1, 0] > 0  # right at the last column
    np.testing.assert_allclose(d[1, :, 1], 0.0, atol=1e-15)  # the middle row looks level


@settings(max_examples=60, deadline=None)
@given(cameras, st.integers(2, 4))
def test_sample_grid_averages_to_pixel_center(cam, s):
    assume(valid(cam))
    center = cam.pixel_directions(1)[:, :, 0]
    grid = cam.pixel_directions(s)
    assert grid.shape == (cam.height, cam.width, s * s, 3)
    np.testing.assert_allclose(grid.mean(axis=2), center, atol=1e-12)
    # sample k = (row a, column b) sits at (i + (b + 0.5)/s, j + (a + 0.5)/s)
    scr = to_screen(cam, cam.eye + grid)
    j, i = np.mgrid[0:cam.height, 0:cam.width]
    for a in range(s):
        for b in range(s):
            k = a * s + b
            np.testing.assert_allclose(scr[:, :, k, 0], i + (b + 0.5) / s, atol=1e-9 * cam.width)
            np.testing.assert_allclose(scr[:, :, k, 1], j + (a + 0.5) / s,
                                       atol=1e-9 * cam.height)


KEYS = [
    {"eye": [0.0, 1.0, 5.0], "target": [0.0, 1.0, 0.0]},
    {"eye": [3.0, 2.0, 4.0], "target": [1.0, 0.5, 0.0], "fov_y": 40.0},
    {"eye": [5.0, 1.5, -1.0], "target": [0.0, 1.0, -2.0], "up": [0.2, 1.0, 0.0]},
    {"eye": [2.0, 3.0, -6.0], "target": [0.0, 0.0, 0.0], "fov_y": 70.0},
]


@pytest.mark.parametrize("interpolation", ["linear", "catmull-rom"])
@pytest.mark.parametrize("keys", [2, 3, 4])
@pytest.mark.parametrize("per_key", [1, 2, 5, 7])
def test_camera_path_passes_every_key(interpolation, keys, per_key):
    frames = 1 + per_key * (keys - 1)
    cfg = CameraConfig.model_validate({
        "eye": [9.0, 9.0, 9.0], "target": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "fov_y": 50.0,
        "path": {"frames": frames, "interpolation": interpolation, "keys": KEYS[:keys]},
    })
    for k, key in enumerate(KEYS[:keys]):
        cam = camera_from_config(cfg, k * per_key)
        np.testing.assert_allclose(cam.eye, key["eye"], atol=1e-12)
        np.testing.assert_allclose(cam.target, key["target"], atol=1e-12)
        np.testing.assert_allclose(cam.up, key.get("up", [0.0, 1.0, 0.0]), atol=1e-12)
        assert cam.fov_y == pytest.approx(key.get("fov_y", 50.0), abs=1e-12)
    # in between keys the path moves: no frame of a segment repeats its start key
    if per_key > 1:
        mid = camera_from_config(cfg, 1)
        assert np.linalg.norm(mid.eye - np.array(KEYS[0]["eye"])) > 1e-3


def test_interpolants_on_a_line_are_exact():
    """Keys evenly spaced on a line: linear and Catmull-Rom both move uniformly."""
    pts = np.array([[0.0, 0, 0], [1, 2, 3], [2, 4, 6], [3, 6, 9]])
    for s in np.linspace(0, 3, 13):
        np.testing.assert_allclose(linear(pts, s), s * pts[1], atol=1e-12)
    # inner segment of Catmull-Rom on collinear evenly spaced keys is linear
    for s in np.linspace(1, 2, 5):
        np.testing.assert_allclose(catmull_rom(pts, s), s * pts[1], atol=1e-12)
    np.testing.assert_allclose(catmull_rom(pts[:1], 0.0), pts[0])
    np.testing.assert_allclose(linear(pts[:1], 0.0), pts[0])


def test_no_path_gives_the_static_camera():
    cfg = CameraConfig.model_validate({"eye": [1.0, 2.0, 3.0], "target": [0.0, 0.0, 0.0],
                                       "width": 32, "height": 16, "near": 0.5, "far": 9.0})
    cam = camera_from_config(cfg, 0)
    np.testing.assert_array_equal(cam.eye, [1, 2, 3])
    assert (cam.width, cam.height, cam.near, cam.far, cam.aspect) == (32, 16, 0.5, 9.0, 2.0)


def test_clip_from_world_is_made_once_per_camera_values():
    """clip_from_world is the view-projection product, made once per camera (by value:
    scenes hand a new Camera each frame) and copied: each call's array is its own, a
    camera with any value changed gets its own product."""
    import dataclasses

    base = Camera(np.array([0.3, 1.2, 4.0]), np.zeros(3), np.array([0.0, 1.0, 0.0]), 50.0,
                  64, 48, 0.1, 100.0)
    first = base.clip_from_world()
    assert first.tobytes() == (base.projection_matrix() @ base.view_matrix()).tobytes()
    first[:] = 0.0  # the caller's own array
    again = dataclasses.replace(base, eye=base.eye.copy()).clip_from_world()
    assert again.tobytes() == (base.projection_matrix() @ base.view_matrix()).tobytes()
    for field, value in (("eye", np.array([0.3, 1.2, 4.5])), ("target", np.ones(3)),
                         ("up", np.array([0.0, 1.0, 0.1])), ("fov_y", 60.0), ("width", 65),
                         ("height", 40), ("near", 0.2), ("far", 90.0)):
        other = dataclasses.replace(base, **{field: value})
        want = other.projection_matrix() @ other.view_matrix()
        assert other.clip_from_world().tobytes() == want.tobytes(), field
        assert not np.array_equal(want, again), field
    for k in range(200):  # a moving camera: every frame its own product
        moved = dataclasses.replace(base, eye=base.eye + [0.01 * k, 0.0, 0.0])
        want = moved.projection_matrix() @ moved.view_matrix()
        assert moved.clip_from_world().tobytes() == want.tobytes()
    # made once: a camera of the same values finds its product kept (the cache holds one
    # entry for them), and the cache stays bounded
    from reflectcli import camera as camera_module

    camera_module._CLIP_FROM_WORLD.clear()
    base.clip_from_world()
    kept = dict(camera_module._CLIP_FROM_WORLD)
    dataclasses.replace(base, eye=base.eye.copy()).clip_from_world()
    assert len(camera_module._CLIP_FROM_WORLD) == 1
    assert next(iter(camera_module._CLIP_FROM_WORLD.values())) is next(iter(kept.values()))
    assert len(camera_module._CLIP_FROM_WORLD) <= 64
