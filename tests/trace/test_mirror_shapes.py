"""Cylinder and mesh mirrors in the ray tracer, and mesh files as objects."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from reflectcli import api
from reflectcli.camera import camera_from_config
from reflectcli.techniques.registry import scene_model

SceneConfig = scene_model()  # the scene model with the technique union

BASE = {
    "scene": {"name": "shapes"},
    "camera": {"eye": [0.0, 1.5, 4.0], "target": [0.0, 1.0, 0.0], "width": 96, "height": 72},
    "materials": {"checker": {"kind": "checker", "scale": [8, 8]},
                  "red": {"kind": "solid", "color": [0.9, 0.1, 0.1]}},
    "objects": [{"name": "room", "shape": "room", "min": [-5, 0, -5], "max": [5, 5, 6],
                 "material": "checker"}],
}


def _render(tmp_path, mirrors, objects=()):
    cfg = SceneConfig.model_validate(
        {**BASE, "objects": BASE["objects"] + list(objects), "mirrors": mirrors,
         "technique": {"name": "raytrace", "max_depth": 1}})
    opened = api.OpenedScene(cfg, str(tmp_path / "scene.toml"), cache=False)
    return opened.render_frame(0), opened.scene


def test_planar_mesh_mirror_equals_quad_mirror(tmp_path):
    corners = np.array([[-1.5, 0.2, -1], [1.5, 0.2, -1], [1.5, 2.2, -1], [-1.5, 2.2, -1]])
    trimesh.Trimesh(corners, [[0, 1, 2], [0, 2, 3]], process=False).export(tmp_path / "m.obj")
    quad, _ = _render(tmp_path, [{"name": "m", "shape": "quad", "corners": corners.tolist()}])
    mesh, _ = _render(tmp_path, [{"name": "m", "shape": "mesh", "path": "m.obj",
                                  "smooth": False}])
    assert quad.mirror_mask.sum() > 1000
    same_mask = quad.mirror_mask == mesh.mirror_mask
    assert same_mask.mean() >= 0.999
    both = quad.mirror_mask & mesh.mirror_mask
    close = np.abs(quad.rgb - mesh.rgb).max(axis=2)[both] <= 1e-4
    assert close.mean() >= 0.995  # checker edges may flip under float32 Embree hits


def test_cylinder_mirror_reflects_by_the_law(tmp_path):
    """At the cylinder's pixels the traced color equals the color the reflected ray
    r = d - 2 (n.d) n finds, computed here in float64 with the radial normal."""
    cyl = {"name": "tube", "shape": "cylinder", "origin": [0, 0.2, 0], "radius": 0.6,
           "height": 1.8}
    frame, scene = _render(tmp_path, [cyl])
    cam = camera_from_config(SceneConfig.model_validate({**BASE, "mirrors": [cyl]}).camera, 0)
    dirs = cam.pixel_directions(1)
    rng = np.random.default_rng(3)
    ys, xs = np.nonzero(frame.mirror_mask)
    pick = rng.choice(len(ys), 40, replace=False)
    origins, rays = [], []
    for y, x in zip(ys[pick], xs[pick], strict=True):
        d = dirs[y, x, 0] / np.linalg.norm(dirs[y, x, 0])
        o = cam.eye
        # ray-cylinder (axis y through origin) in float64
        a = d[0] ** 2 + d[2] ** 2
        b = o[0] * d[0] + o[2] * d[2]
        c = o[0] ** 2 + o[2] ** 2 - 0.36
        t = (-b - np.sqrt(b * b - a * c)) / a
        p = o + t * d
        n = np.array([p[0], 0.0, p[2]]) / 0.6
        r = d - 2 * (n @ d) * n
        origins.append(p + 1e-3 * r)
        rays.append(r)
    # trace the reflected rays as primary rays of a camera-free query against the same scene
    from reflectcli.trace.tracer import build_accelerators

    acc = build_accelerators(scene.geometry(0))
    t, prim, u, v = acc.objects.intersect(np.array(origins, np.float32),
                                          np.array(rays, np.float32),
                                          np.full(len(rays), 1e30, np.float32))
    tris = scene.geometry(0).objects
    b0 = 1 - u - v
    uv = (b0[:, None] * tris.uvs[prim, 0] + u[:, None] * tris.uvs[prim, 1]
          + v[:, None] * tris.uvs[prim, 2])
    checker = (np.floor(uv[:, 0] * 8) + np.floor(uv[:, 1] * 8)) % 2
    expected = np.where(checker[:, None] == 0, 0.0, 1.0) * np.ones(3)
    got = frame.rgb[ys[pick], xs[pick]]
    agree = np.abs(got - expected).max(axis=1) < 1e-3
    assert agree.mean() >= 0.9  # pixels on a checker edge may differ; most must agree


@pytest.mark.parametrize("ext", ["obj", "ply", "stl", "glb"])
def test_mesh_file_objects_render(tmp_path, ext):
    box = trimesh.creation.box(extents=[1, 1, 1])
    box.apply_translation([0, 1, 0])
    box.export(tmp_path / f"box.{ext}")
    frame, scene = _render(tmp_path, [], [{"name": "box", "shape": "mesh",
                                           "path": f"box.{ext}", "material": "red"}])
    box_pixels = frame.surface == 1
    assert box_pixels.sum() > 200
    expected = np.broadcast_to([0.9, 0.1, 0.1], (int(box_pixels.sum()), 3))
    np.testing.assert_allclose(frame.rgb[box_pixels], expected, atol=1e-6)
