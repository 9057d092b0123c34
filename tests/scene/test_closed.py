"""The solids `closed_outward` calls closed are: their meshes watertight, wound one way
and outward (positive volume), as trimesh finds them after welding; the geometry gives
their world boxes, and culling their back faces from outside changes no pixel."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import trimesh

from reflectcli.loading import load_config
from reflectcli.scene.build import build_scene, closed_outward, object_mesh

SOLIDS = [
    'shape = "box"\nmin = [-1, 0, -2]\nmax = [1, 0.5, 2]',
    'shape = "sphere"\nradius = 0.7\nsegments = 3',
    'shape = "sphere"\nradius = 2\nsegments = 48',
    'shape = "sphere"\ntessellation = "ico"\nsubdivisions = 0',
    'shape = "sphere"\ntessellation = "ico"\nsubdivisions = 3',
    'shape = "cylinder"\nradius = 0.5\nheight = 2\nsegments = 3',
    'shape = "cylinder"\nsegments = 40',
    'shape = "cone"\nsegments = 3',
    'shape = "cone"\nradius = 0.3\nheight = 4\nsegments = 64',
    'shape = "pyramid"\nsize = 2\nheight = 0.5',
    'shape = "torus"\nmajor_radius = 1\nminor_radius = 0.9\nmajor_segments = 3\n'
    'minor_segments = 3',
    'shape = "torus"',
]
OPEN = [
    'shape = "cylinder"\ncaps = false',
    'shape = "torus"\nmajor_radius = 0.5\nminor_radius = 0.6',
    'shape = "quad"\ncorners = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]',
    'shape = "room"\nmin = [0, 0, 0]\nmax = [1, 1, 1]',
    'shape = "teapot"',
]


def _scene(objects: list[str], mirrors: str = "") -> str:
    body = "".join(f'\n[[objects]]\nname = "o{i}"\nmaterial = "m"\n{o}\n'
                   for i, o in enumerate(objects))
    return f"""
[scene]
name = "closed"
[camera]
eye = [0.0, 1.0, 9.0]
target = [0.0, 0.5, 0.0]
width = 160
height = 120
[materials.m]
kind = "checker"
color0 = [0.1, 0.2, 0.3]
color1 = [0.9, 0.8, 0.7]
{body}
{mirrors}
[technique]
name = "raster"
"""


def _config(tmp_path, objects: list[str], mirrors: str = ""):
    path = tmp_path / "closed.toml"
    path.write_text(_scene(objects, mirrors))
    return load_config(str(path))[0]


@pytest.mark.parametrize("solid", SOLIDS)
def test_closed_solids_are_watertight_and_outward(tmp_path, solid):
    obj = _config(tmp_path, [solid]).objects[0]
    assert closed_outward(obj)
    mesh = object_mesh(obj, "closed.toml").without_degenerate()
    tm = trimesh.Trimesh(mesh.corners.reshape(-1, 3),
                         np.arange(3 * mesh.triangle_count).reshape(-1, 3), process=False)
    tm.merge_vertices(merge_tex=True, merge_norm=True, digits_vertex=9)
    assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0


@pytest.mark.parametrize("solid", OPEN)
def test_open_surfaces_are_not_called_closed(tmp_path, solid):
    assert not closed_outward(_config(tmp_path, [solid]).objects[0])


def test_culling_closed_solids_from_outside_keeps_the_buffers(tmp_path):
    """Every solid above side by side (one moving), and a sphere mirror: the primary
    pass, which culls their back faces (raster/closed.py), draws the very triangles and
    depths an unculled pass draws here (only an exact silhouette tie could differ: see the
    next test); from inside the sphere nothing is culled."""
    from reflectcli.camera import camera_from_config
    from reflectcli.raster.closed import hidden_back_faces
    from reflectcli.raster.primary import render_primary
    from reflectcli.raster.rasterize import rasterize

    placed = [f"{s}\ntransform.translate = [{2.5 * (i % 4) - 4}, 0, {-2.5 * (i // 4)}]"
              for i, s in enumerate(SOLIDS)]
    placed[1] = SOLIDS[1] + ("\n[[objects.motion]]\nframe = 0\ntranslate = [0, 0, 0]\n"
                             "[[objects.motion]]\nframe = 1\ntranslate = [1, 0, 0]")
    mirror = ('[[mirrors]]\nname = "ball"\nshape = "sphere"\ncenter = [0, 2, 2]\n'
              'radius = 0.8\n')
    cfg = _config(tmp_path, placed + OPEN[:2], mirror)
    scene = build_scene(cfg, str(tmp_path / "closed.toml"))
    for frame in (0, 1):
        camera = camera_from_config(cfg.camera, frame)
        geometry = scene.geometry(frame)
        hidden = hidden_back_faces(geometry, camera)
        assert hidden is not None and hidden.sum() == len(SOLIDS) + 1
        tris = geometry.all_triangles()
        got = render_primary(scene, frame, camera).buffers
        plain = (tris.surface >= scene.n_objects).astype(np.uint8)
        want = rasterize(tris.corners, plain, camera.clip_from_world(), camera.width,
                         camera.height)
        assert (got.triangle >= 0).mean() > 0.15
        assert got.triangle.tobytes() == want.triangle.tobytes()
        assert got.depth.tobytes() == want.depth.tobytes()
    # the moving sphere's box follows it
    moved = scene.geometry(1).closed_boxes[1] - scene.geometry(0).closed_boxes[1]
    np.testing.assert_allclose(moved, [1, 0, 0, 1, 0, 0], atol=1e-6)
    inside = dataclasses.replace(camera_from_config(cfg.camera, 0),
                                 eye=np.array([0.0, 2.0, 2.0]))
    hidden = hidden_back_faces(scene.geometry(0), inside)
    assert not hidden[scene.n_objects]


def test_a_silhouette_tie_goes_to_the_front_face():
    """A back face (index 0) and a front face (index 1) folded along a shared vertical edge
    through pixel centres, at the same depth there: unculled the tie goes to the lower
    index, the back face; flagged, the front face has those centres."""
    from reflectcli.camera import Camera
    from reflectcli.raster.rasterize import FLAG_CULL_BACK, rasterize

    cam = Camera(np.array([0.0, 0.0, 5.0]), np.zeros(3), np.array([0.0, 1.0, 0.0]), 60.0,
                 8, 8, 0.5, 50.0)
    m = cam.clip_from_world()
    # the shared edge through the pixel centres of column 4 (NDC x 0.125 at depth 5); the
    # back face folds behind the front one, both to the edge's right
    x = 0.125 * np.tan(np.radians(30.0)) * 5.0
    a, b = [x, -1.0, 0.0], [x, 1.0, 0.0]
    front = [a, [x + 1.5, 0.0, 0.0], b]  # counter-clockwise seen from the eye
    back = [a, b, [x + 1.5, 0.0, -1.0]]  # clockwise: turned away
    corners = np.array([back, front], np.float32)
    plain = rasterize(corners, np.zeros(2, np.uint8), m, 8, 8)
    culled = rasterize(corners, np.full(2, FLAG_CULL_BACK, np.uint8), m, 8, 8)
    column = plain.triangle[:, 4]
    assert (column == 0).any(), "the case is gone: the back face won no tie"
    assert np.all(culled.triangle[:, 4][column >= 0] == 1)
    assert np.all((culled.triangle == plain.triangle) | (plain.triangle == 0))


def test_a_solid_too_small_for_its_triangles_is_open(tmp_path):
    """A sphere small enough that real triangles fall below the degenerate-area cut has
    holes: not culled (no box)."""
    cfg = _config(tmp_path, ['shape = "sphere"\nradius = 1e-6', SOLIDS[1]])
    scene = build_scene(cfg, str(tmp_path / "closed.toml"))
    boxes = scene.geometry(0).closed_boxes
    assert np.isnan(boxes[0]).all() and not np.isnan(boxes[1]).any()
