"""The closed pieces meshes carry (Mesh.pieces: the solids, each part of the music room's
clutter) are: watertight, wound one way and outward (positive volume), as trimesh finds
them after welding; the geometry gives their world boxes, and culling their back faces from
outside, in the primary pass and in planar mirrors' reflection passes, changes no pixel."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import trimesh

from reflectcli.loading import load_config
from reflectcli.scene.build import build_scene, object_mesh
from reflectcli.scene.mesh import Mesh

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


def _closes_outward(corners: np.ndarray) -> bool:
    tm = trimesh.Trimesh(corners.reshape(-1, 3), np.arange(3 * len(corners)).reshape(-1, 3),
                         process=False)
    tm.merge_vertices(merge_tex=True, merge_norm=True, digits_vertex=9)
    return bool(tm.is_watertight and tm.is_winding_consistent and tm.volume > 0)


@pytest.mark.parametrize("solid", SOLIDS)
def test_closed_solids_are_watertight_and_outward(tmp_path, solid):
    obj = _config(tmp_path, [solid]).objects[0]
    mesh = object_mesh(obj, "closed.toml").without_degenerate()
    assert mesh.pieces is not None and np.all(mesh.pieces == 0)
    assert _closes_outward(mesh.corners)


@pytest.mark.parametrize("solid", OPEN)
def test_open_surfaces_are_not_called_closed(tmp_path, solid):
    pieces = object_mesh(_config(tmp_path, [solid]).objects[0], "closed.toml").pieces
    assert pieces is None or np.all(pieces < 0)


@pytest.mark.parametrize(("lo", "hi"), [([0, 0, 0], [1, 0, 1]), ([1, 0, 0], [0, 1, 1])])
def test_a_box_without_volume_is_open(lo, hi):
    """primitives.box (the clutter's, which the config's max > min check does not see):
    flat (top and bottom coincide, the zero-area sides are cut without opening it) or
    turned inside out, it is no piece."""
    from reflectcli.scene import primitives

    pieces = primitives.box(lo, hi).without_degenerate().pieces
    assert pieces is None or np.all(pieces < 0)


@pytest.mark.parametrize("budget", [2000, 60000])
def test_every_part_of_the_clutter_is_a_closed_piece(budget):
    """The music room's furniture is made of solids (several overlapping): each is a piece,
    watertight and outward after its placement (scaled, turned, tilted)."""
    from reflectcli.scene.procedural import music_room_clutter

    mesh = music_room_clutter(budget, [-10, 0, -7], [10, 4.5, 7]).without_degenerate()
    assert mesh.pieces is not None and np.all(mesh.pieces >= 0)
    assert mesh.piece_count > 50
    for k in range(mesh.piece_count):
        assert _closes_outward(mesh.corners[mesh.pieces == k]), k


def test_pieces_follow_concatenation_mirroring_and_degenerate_cuts():
    """Concatenation renumbers pieces after the ones before (an open mesh's triangles -1);
    a mirroring transform flips the winding and keeps each piece outward; a piece that
    loses a triangle with area to the degenerate cut is open, another one stays."""
    from reflectcli.scene import primitives

    ball = primitives.uv_sphere(1.0, 12)
    joined = Mesh.concatenate([ball, primitives.quad([[0, 0, 0], [1, 0, 0], [1, 1, 0],
                                                      [0, 1, 0]]), primitives.box([0, 0, 0],
                                                                                 [1, 2, 3])])
    counts = (ball.triangle_count, 2, 12)
    assert joined.piece_count == 2
    np.testing.assert_array_equal(joined.pieces, np.repeat([0, -1, 1], counts))
    mirrored = joined.transformed(np.diag([-1.0, 2.0, 1.0, 1.0]))
    np.testing.assert_array_equal(mirrored.pieces, joined.pieces)
    assert _closes_outward(mirrored.corners[mirrored.pieces == 0])
    assert _closes_outward(mirrored.corners[mirrored.pieces == 1])
    # radius 3e-6: 72 of the 120 triangles keep an area above the cut (1e-6 kept none,
    # which held nothing: an empty piece is open either way)
    tiny = Mesh.concatenate([primitives.uv_sphere(3e-6, 12), ball]).without_degenerate()
    assert 0 < tiny.triangle_count - ball.triangle_count < 120
    assert np.all(tiny.pieces[:-ball.triangle_count] == -1)
    assert np.all(tiny.pieces[-ball.triangle_count:] == 1)


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
    geometry = scene.geometry(0)
    ball = geometry.closed_piece[geometry.all_triangles().surface == scene.n_objects]
    assert np.all(ball == len(SOLIDS))
    assert not hidden_back_faces(geometry, inside)[len(SOLIDS)]


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
    holes: not culled (no piece)."""
    # radius 1e-5: 704 of its 960 triangles stay (at 1e-6 none did: nothing to hold)
    cfg = _config(tmp_path, ['shape = "sphere"\nradius = 1e-5', SOLIDS[1]])
    scene = build_scene(cfg, str(tmp_path / "closed.toml"))
    geometry = scene.geometry(0)
    piece = geometry.closed_piece
    surface = geometry.all_triangles().surface
    assert 0 < np.count_nonzero(surface == 0) < 960
    assert np.all(piece[surface == 0] == -1) and np.all(piece[surface == 1] == 0)
    assert not np.isnan(geometry.closed_boxes[0]).any()


@pytest.mark.parametrize("clip", ["oblique", "plane", "none"])
def test_culling_in_reflection_passes_keeps_the_frame(tmp_path, monkeypatch, clip):
    """Two facing planar mirrors (reflections of reflections: both screen windings), one
    behind the solids, one behind the eye; a box cut by a mirror's plane (its inside shows,
    not culled there): rerender's
    frames with the reflection passes' culling are those without it, byte for byte, and the
    passes did cull."""
    import reflectcli.techniques.rerender.technique as rerender
    from reflectcli import api
    from reflectcli.raster import closed

    placed = [f"{s}\ntransform.translate = [{1.6 * (i % 4) - 2.4}, 0.2, {-1.6 * (i // 4)}]"
              for i, s in enumerate(SOLIDS[:8])]
    # a box the far mirror's plane cuts (its inside shows in the reflection)
    placed.append('shape = "box"\nmin = [-2, 0.5, -6.3]\nmax = [-1.2, 1.5, -5.7]')
    mirrors = "".join(
        f'[[mirrors]]\nname = "m{i}"\nshape = "rectangle"\ncenter = [0, 1, {z}]\n'
        f'normal = [0, 0, {n}]\nsize = [12, 6]\nreflectance = 0.9\n'
        for i, (z, n) in enumerate([(-6.0, 1), (10.5, -1)]))
    path = tmp_path / "closed.toml"
    path.write_text(_scene(placed, mirrors).replace('name = "raster"', f'name = "rerender"\n'
                                                     f'max_depth = 3\nclip = "{clip}"'))
    real = closed.reflection_pass_flags
    culled = []

    def counting(geometry, flags, *args):
        out = real(geometry, flags, *args)
        culled.append(int(np.count_nonzero(out & (closed.FLAG_CULL_BACK
                                                  | closed.FLAG_CULL_FRONT))))
        return out

    def frame(flags_of):
        monkeypatch.setattr(rerender, "reflection_pass_flags", flags_of)
        opened = api.open_scene(str(path), technique=None, overrides=[], threads=2, cache=False)
        opened.prepare()
        return opened.render_frame(0)

    def unculled(geometry, flags, surface, *args):
        tris = geometry.all_triangles()
        return flags | np.where(tris.surface == surface, closed.FLAG_SKIP, 0).astype(np.uint8)

    got, want = frame(counting), frame(unculled)
    assert got.stats["passes"] == 4 and len(culled) == 3 and min(culled) > 0  # levels 1-3
    assert got.rgb.tobytes() == want.rgb.tobytes()
    assert got.surface.tobytes() == want.surface.tobytes()


def test_reflection_pass_flags_cull_only_pieces_seen_whole_from_outside(tmp_path):
    """A reflection pass culls a piece only when the reflected eye is outside its box and
    the clip plane leaves it whole (kept side or clipped side; a cut piece shows its
    inside); odd levels cull the screen's front faces, even ones its back faces; the mirror
    itself is skipped."""
    from reflectcli.camera import camera_from_config
    from reflectcli.raster import closed
    from reflectcli.raster.rasterize import RasterWorkspace

    boxes = ['shape = "box"\nmin = [-1, 0, -1]\nmax = [0, 1, 0]',  # kept side
             'shape = "box"\nmin = [-1, 0, -4]\nmax = [0, 1, -3]',  # clipped side
             'shape = "box"\nmin = [1, 0, -2.5]\nmax = [2, 1, -1.5]',  # cut by the plane
             'shape = "box"\nmin = [3, 0, 3]\nmax = [5, 2, 5]']  # holds the eye
    mirror = ('[[mirrors]]\nname = "m"\nshape = "rectangle"\ncenter = [0, 1, -2]\n'
              'normal = [0, 0, 1]\nsize = [2, 2]\n')
    cfg = _config(tmp_path, boxes, mirror)
    scene = build_scene(cfg, str(tmp_path / "closed.toml"))
    geometry = scene.geometry(0)
    tris = geometry.all_triangles()
    plain = (tris.surface >= scene.n_objects).astype(np.uint8)
    camera = camera_from_config(cfg.camera, 0)
    plane = np.array([0.0, 0.0, 1.0, 2.0])  # z >= -2 kept
    for level, flag in ((1, closed.FLAG_CULL_FRONT), (2, closed.FLAG_CULL_BACK)):
        flags = closed.reflection_pass_flags(geometry, plain, scene.n_objects,
                                             np.array([4.0, 1.0, 4.0]), plane, camera, level,
                                             RasterWorkspace())
        per_surface = [set(np.unique(flags[tris.surface == s]).tolist()) for s in range(5)]
        assert per_surface == [{flag}, {flag}, {0}, {0},
                               {closed.FLAG_MIRROR | closed.FLAG_SKIP}]


def test_reflection_pass_flags_kept_only_while_the_same(tmp_path):
    """The pass flags kept in the workspace (per mirror and parity) are those made afresh
    whenever the culled pieces (the reflected eye moved into a box) or the primary pass's
    flags change."""
    from reflectcli.camera import camera_from_config
    from reflectcli.raster import closed
    from reflectcli.raster.rasterize import RasterWorkspace

    cfg = _config(tmp_path, ['shape = "box"\nmin = [-1, 0, -1]\nmax = [0, 1, 0]'],
                  '[[mirrors]]\nname = "m"\nshape = "rectangle"\ncenter = [0, 1, -2]\n'
                  'normal = [0, 0, 1]\nsize = [2, 2]\n')
    scene = build_scene(cfg, str(tmp_path / "closed.toml"))
    geometry = scene.geometry(0)
    tris = geometry.all_triangles()
    camera = camera_from_config(cfg.camera, 0)
    plane = np.array([0.0, 0.0, 1.0, 2.0])
    plain = (tris.surface >= scene.n_objects).astype(np.uint8)
    other = plain | np.where(tris.surface == 0, closed.FLAG_SKIP, 0).astype(np.uint8)
    ws = RasterWorkspace()
    calls = [(plain, [4.0, 1.0, 4.0]), (plain, [-0.5, 0.5, -0.5]), (other, [-0.5, 0.5, -0.5]),
             (plain, [4.0, 1.0, 4.0])]
    for flags, eye in calls:
        got = closed.reflection_pass_flags(geometry, flags, scene.n_objects, np.array(eye),
                                           plane, camera, 1, ws)
        want = closed.reflection_pass_flags(geometry, flags, scene.n_objects, np.array(eye),
                                            plane, camera, 1, RasterWorkspace())
        assert got.tobytes() == want.tobytes(), eye


def test_primary_pass_beside_a_solid_the_near_plane_cuts(tmp_path):
    """An eye closer to a solid than the near plane reaches (outside its box): the near
    plane cuts it open, its back faces show and are not culled."""
    from reflectcli.camera import Camera
    from reflectcli.raster.primary import render_primary
    from reflectcli.raster.rasterize import rasterize

    cfg = _config(tmp_path, [SOLIDS[0], SOLIDS[2]])
    scene = build_scene(cfg, str(tmp_path / "closed.toml"))
    tris = scene.geometry(0).all_triangles()
    plain = (tris.surface >= scene.n_objects).astype(np.uint8)
    for eye, target in (([0.0, 0.25, 2.2], [0.0, 0.25, 0.0]), ([0.3, 2.15, 0.2], [0.0, 0.0, 0.0]),
                        ([1.1, 0.3, 1.9], [0.0, 0.3, 0.0])):
        camera = Camera(np.array(eye), np.array(target), np.array([0.0, 1.0, 0.0]), 70.0, 160,
                        120, 0.3, 50.0)
        got = render_primary(scene, 0, camera).buffers
        want = rasterize(tris.corners, plain, camera.clip_from_world(), camera.width,
                         camera.height)
        assert got.triangle.tobytes() == want.triangle.tobytes(), eye
        assert got.depth.tobytes() == want.depth.tobytes(), eye


@pytest.mark.parametrize("clip", ["oblique", "plane", "none"])
def test_every_reflection_pass_draws_what_an_unculled_pass_draws(tmp_path, monkeypatch, clip):
    """Each of rerender's reflection passes, drawn over the whole screen with and without
    its culling flags, gives the same buffers: a floor mirror and a wall mirror (levels 1-2,
    both parities), solids seen in them, a box through the floor mirror's plane (its inside
    shows in the reflection), a box around the wall mirror's reflected eye (its inside
    fills that pass in clip "none"), and an eye a little off the wall mirror (the near
    plane of the reflected eye cuts what stands in front of it)."""
    import reflectcli.techniques.rerender.technique as rerender
    from reflectcli import api
    from reflectcli.raster.rasterize import FLAG_CULL_BACK, FLAG_CULL_FRONT

    placed = [f"{s}\ntransform.translate = [{1.5 * (i % 4) - 2.2}, 0.3, {-1.4 * (i // 4) + 1}]"
              for i, s in enumerate(SOLIDS[1:9])]
    placed += ['shape = "box"\nmin = [-3.2, -0.4, 1.5]\nmax = [-2.4, 0.5, 2.3]',
               'shape = "box"\nmin = [-0.6, 2.4, -16.6]\nmax = [0.6, 3.6, -15.4]',
               'shape = "box"\nmin = [1.03, 1.0, -3.99]\nmax = [1.2, 1.2, -3.93]']
    mirrors = ('[[mirrors]]\nname = "floor"\nshape = "rectangle"\ncenter = [0, 0, 0]\n'
               'normal = [0, 1, 0]\nsize = [16, 16]\nup = [0, 0, -1]\nreflectance = 0.9\n'
               '[[mirrors]]\nname = "wall"\nshape = "rectangle"\ncenter = [0, 2, -4]\n'
               'normal = [0, 0, 1]\nsize = [12, 4]\nreflectance = 0.9\n')
    path = tmp_path / "closed.toml"
    path.write_text(_scene(placed, mirrors).replace('name = "raster"', f'name = "rerender"\n'
                                                     f'max_depth = 3\nclip = "{clip}"'))
    real = rerender.rasterize
    seen = {"passes": 0, "culled": 0, "pixels": 0}

    def both(corners, flags, m, width, height, planes=None, **options):
        plain = flags & ~np.uint8(FLAG_CULL_BACK | FLAG_CULL_FRONT)
        got = real(corners, flags, m, width, height, planes)
        want = real(corners, plain, m, width, height, planes)
        assert got.triangle.tobytes() == want.triangle.tobytes()
        assert got.depth.tobytes() == want.depth.tobytes()
        seen["passes"] += 1
        seen["culled"] += int(np.count_nonzero(flags != plain))
        seen["pixels"] += int(np.count_nonzero(want.triangle >= 0))
        return real(corners, flags, m, width, height, planes, **options)

    monkeypatch.setattr(rerender, "rasterize", both)
    for eye, target in (("[0.0, 3.0, 8.0]", "[0.0, 0.5, 0.0]"),
                        ("[1.0, 1.1, -3.97]", "[3.0, 1.1, -4.6]")):
        opened = api.open_scene(str(path), technique=None, threads=2, cache=False,
                                overrides=[f"camera.eye={eye}", f"camera.target={target}",
                                           "camera.near=0.05", "camera.fov_y=90"])
        opened.prepare()
        opened.render_frame(0)
    assert seen["passes"] >= 6 and seen["culled"] > 0 and seen["pixels"] > 0
