"""The ray tracer obeys the mirror laws.

(a) A planar mirror filling the view shows exactly what a camera at the mirrored eye sees
    with the mirror removed, flipped left-right: pixel (i, j) <-> (W - 1 - i, j).
    Why exactly: the mirrored camera's right vector is -R right (a reflection reverses
    handedness) while its up and forward are R up and R forward, so its ray through screen
    x' = -x is the reflection of the real ray through x; pixel centers are symmetric.
(b) A sphere mirror: the color at each mirror pixel is the color found along
    r = 2 n (n.v) - v, with the hit, normal and reflection computed here in float64 and the
    reflected ray met with the checker room in closed form (the room's documented UV layout).
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from reflectcli.camera import Camera, camera_from_config
from reflectcli.geometry import reflect_point, reflect_vector
from reflectcli.scene.build import build_scene
from reflectcli.techniques.raytrace.technique import Raytrace
from reflectcli.techniques.registry import scene_model

ROOM_MIN, ROOM_MAX = np.array([-5.0, 0.0, -5.0]), np.array([5.0, 5.0, 6.0])
CHECKER = {"kind": "checker", "color0": [0.1, 0.2, 0.3], "color1": [0.9, 0.8, 0.7],
           "scale": [8, 6]}

SceneConfig = scene_model()  # the scene model with the technique union


def base_scene(shading: str) -> dict:
    return {
        "scene": {"name": "laws", "shading": shading, "ambient": 0.2},
        "camera": {"eye": [0.3, 2.5, 2.0], "target": [0.1, 2.3, -3.0], "fov_y": 50.0,
                   "width": 120, "height": 90},
        "lights": [{"kind": "point", "position": [1.0, 4.0, 3.0], "intensity": 8.0}],
        "materials": {"checker": CHECKER, "red": {"kind": "solid", "color": [0.8, 0.1, 0.1]}},
        "objects": [
            {"name": "room", "shape": "room", "min": ROOM_MIN.tolist(),
             "max": ROOM_MAX.tolist(), "material": "checker"},
            # behind the real camera: visible only in the mirror
            {"name": "box", "shape": "box", "min": [-0.8, 1.5, 3.5], "max": [0.6, 3.2, 4.5],
             "material": "red"},
            {"name": "ball", "shape": "sphere", "radius": 0.7, "material": "checker",
             "transform": {"translate": [1.5, 2.0, 4.0]}},
        ],
        "mirrors": [],
    }


def render(cfg_dict: dict, tmp_path, max_depth: int, camera: Camera | None = None):
    cfg = SceneConfig.model_validate(cfg_dict)
    scene = build_scene(cfg, str(tmp_path / "x.toml"))
    tech = Raytrace(Raytrace.Params(max_depth=max_depth), threads=2)
    cam = camera if camera is not None else camera_from_config(cfg.camera, 0)
    return tech.render(tech.prepare(scene), 0, cam), cam


def differs_from_a_neighbour(rgb: np.ndarray) -> np.ndarray:
    """Pixels whose color differs from one of their 4-neighbours: a color boundary (checker
    edge, silhouette) passes within a pixel of the center."""
    diff = np.zeros(rgb.shape[:2], bool)
    step = np.abs(np.diff(rgb, axis=0)).max(axis=2) > 0
    diff[1:] |= step
    diff[:-1] |= step
    step = np.abs(np.diff(rgb, axis=1)).max(axis=2) > 0
    diff[:, 1:] |= step
    diff[:, :-1] |= step
    return diff


@pytest.mark.parametrize("shading", ["unlit", "lambert"])
def test_planar_mirror_equals_mirrored_camera(tmp_path, shading):
    scene = base_scene(shading)
    # a head-on mirror one unit in front of the eye, its front (+z) toward the camera
    z = 1.0
    corners = [[-3, 0.5, z], [3, 0.5, z], [3, 4.5, z], [-3, 4.5, z]]
    with_mirror = copy.deepcopy(scene)
    with_mirror["mirrors"] = [{"name": "m", "shape": "quad", "corners": corners,
                               "reflectance": 1.0}]
    frame, cam = render(with_mirror, tmp_path, max_depth=1)
    assert frame.mirror_mask.all()  # the mirror fills the view

    n, d = np.array([0.0, 0.0, 1.0]), -z
    mirrored = Camera(reflect_point(cam.eye, n, d), reflect_point(cam.target, n, d),
                      reflect_vector(cam.up, n), cam.fov_y, cam.width, cam.height,
                      cam.near, cam.far)
    direct, _ = render(scene, tmp_path, max_depth=0, camera=mirrored)
    assert (direct.surface == 1).sum() > 100  # the box behind the camera is in the reflection
    assert (direct.surface == 2).sum() > 100

    expected = direct.rgb[:, ::-1]
    mismatch = np.abs(frame.rgb - expected).max(axis=2) > 1e-5
    # edge pixels: the unlit albedo (checker cells, silhouettes) changes to a 4-neighbour
    albedo = direct if shading == "unlit" else render(
        {**scene, "scene": {**scene["scene"], "shading": "unlit"}}, tmp_path, max_depth=0,
        camera=mirrored)[0]
    edges = differs_from_a_neighbour(albedo.rgb[:, ::-1])
    assert edges.mean() < 0.3
    # float32 hit points may put a pixel on the other side of a boundary, nowhere else
    assert not np.any(mismatch & ~edges)
    assert mismatch.sum() <= 0.001 * mismatch.size
    agree = ~edges
    np.testing.assert_allclose(frame.rgb[agree], expected[agree], atol=1e-5)


def room_color(q: np.ndarray, face: np.ndarray) -> np.ndarray:
    """Checker albedo (unlit) of room points, from the room's UV contract, and the distance
    (in checker cells) of each point to the nearest cell boundary."""
    lo, hi = ROOM_MIN, ROOM_MAX
    span = hi - lo
    x, y, zz = ((q - lo) / span).T
    u = np.select([face == 0, face == 1, face == 2, face == 3, face == 4, face == 5],
                  [1 - zz, zz, x, x, x, 1 - x])
    v = np.select([face == 0, face == 1, face == 2, face == 3, face == 4, face == 5],
                  [y, y, 1 - zz, zz, y, y])
    su, sv = CHECKER["scale"]
    i, j = np.floor(u * su), np.floor(v * sv)
    parity = (i + j) % 2
    colors = np.where(parity[:, None] == 0, CHECKER["color0"], CHECKER["color1"])
    fu, fv = u * su - i, v * sv - j
    margin = np.minimum(np.minimum(fu, 1 - fu), np.minimum(fv, 1 - fv))
    return colors, margin


def exit_room(p: np.ndarray, r: np.ndarray):
    """Where rays from inside the box leave it: point and face
    (0 west x-, 1 east x+, 2 floor y-, 3 ceiling y+, 4 north z-, 5 south z+)."""
    with np.errstate(divide="ignore"):
        t_hi = (ROOM_MAX - p) / r
        t_lo = (ROOM_MIN - p) / r
    t_axis = np.where(r > 0, t_hi, t_lo)
    axis = t_axis.argmin(axis=1)
    t = t_axis[np.arange(len(p)), axis]
    face = 2 * axis + (r[np.arange(len(p)), axis] > 0)
    return p + t[:, None] * r, face


def test_sphere_mirror_reflects_by_the_law(tmp_path):
    center, radius = np.array([0.2, 2.0, -1.0]), 1.2
    scene = base_scene("unlit")
    scene["objects"] = scene["objects"][:1]  # the room alone
    scene["mirrors"] = [{"name": "ball", "shape": "sphere", "center": center.tolist(),
                         "radius": radius, "reflectance": 1.0}]
    frame, cam = render(scene, tmp_path, max_depth=1)
    mirror = frame.mirror_mask
    assert mirror.sum() > 1000

    d = cam.pixel_directions(1)[:, :, 0][mirror]  # float64
    o = cam.eye
    # first hit on the sphere, in float64
    oc = o - center
    b = d @ oc
    a = np.einsum("pk,pk->p", d, d)
    disc = b * b - a * (oc @ oc - radius * radius)
    assert np.all(disc > 0)
    t = (-b - np.sqrt(disc)) / a
    p = o + t[:, None] * d
    n = (p - center) / radius
    v = -d / np.linalg.norm(d, axis=1, keepdims=True)
    r = 2 * n * np.einsum("pk,pk->p", n, v)[:, None] - v  # the law
    np.testing.assert_allclose(np.linalg.norm(r, axis=1), 1.0, atol=1e-12)
    q, face = exit_room(p, r)
    expected, margin = room_color(q, face)
    got = frame.rgb[mirror]
    # near the silhouette (grazing, n.v -> 0) the reflection is ill-conditioned; a float32
    # tracer may also land on the other side of a checker boundary within a hair of it
    clear = (margin > 1e-4) & (np.einsum("pk,pk->p", n, v) > 1e-3)
    assert clear.mean() >= 0.99
    np.testing.assert_allclose(got[clear], expected[clear], atol=1e-6)
    # the excluded pixels still hold one of the two checker colors
    either = np.minimum(np.abs(got - CHECKER["color0"]).max(1),
                        np.abs(got - CHECKER["color1"]).max(1))
    assert either.max() <= 1e-6


def test_reflected_hit_marks_reflections_of_geometry():
    """`reflected_hit` is 1 on mirror pixels whose reflected ray meets geometry and 0 where
    it leaves for the background (teapot-floor's floor mirror shows the open sky above the
    backdrop), 0 off the mirrors; only traced when reflections are (max_depth >= 1)."""
    from conftest import render_frame

    size = ("camera.width=160", "camera.height=120")
    frame, scene = render_frame("teapot-floor", "raytrace", 0, ("technique.max_depth=1", *size))
    hit = frame.extra["reflected_hit"]
    mirror = frame.mirror_mask
    assert set(np.unique(hit)) == {0.0, 1.0}
    assert not hit[~mirror].any()
    on_mirror = hit[mirror]
    assert 0.05 < on_mirror.mean() < 0.95  # both kinds of reflection are in view
    # where the reflection is the background, the pixel shows r * background + (1-r) * base
    k = 0
    r, base = scene.mirrors.reflectance[k], scene.mirrors.base[k]
    sky = mirror & (hit == 0)
    expected = (1 - r) * base + r * np.asarray(scene.background)
    np.testing.assert_allclose(frame.rgb[sky], np.broadcast_to(expected, frame.rgb[sky].shape),
                               atol=1e-6)
    flat, _ = render_frame("teapot-floor", "raytrace", 0, ("technique.max_depth=0", *size))
    assert "reflected_hit" not in flat.extra
