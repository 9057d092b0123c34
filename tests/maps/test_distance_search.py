"""The distance-map search kernel against its slow twin (tests/naive.py), and the
depth-peeled capture against a ray-cast definition of its layers."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from reflectcli.maps.cube import face_bases
from reflectcli.maps.distance import capture_distance_faces, inverse_depth
from reflectcli.maps.distance_search import _search_work, search_ray, search_texels
from reflectcli.maps.update import face_capture_frames, faces_updated, map_capture_frame

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from naive import face_uv, naive_search  # noqa: E402


def _box_map(res=16, layers=2, seed=0):
    """A map of a box room [-4, 4]^3 (layer 0; ids by wall) with a random extra layer of
    blocks in front (layer order by depth), plus random colours."""
    rng = np.random.default_rng(seed)
    bases = face_bases()
    q = np.zeros((layers, 6, res, res), np.float32)
    surface = np.full((layers, 6, res, res), -1, np.int32)
    depth = np.full((layers, 6, res, res), np.inf, np.float32)
    for f in range(6):
        depth[-1, f] = 4.0  # the wall of face f: eye depth 4 along its axis
        surface[-1, f] = f
        if layers > 1:
            blocks = rng.random((res // 4, res // 4)) < 0.3
            near = np.kron(blocks, np.ones((4, 4), bool))
            depth[0, f] = np.where(near, 2.0 + rng.random(), 4.0)
            surface[0, f] = np.where(near, 6 + f, f)
            depth[-1, f] = np.where(near, 4.0, np.inf)
            surface[-1, f] = np.where(near, f, -1)
    q[:] = inverse_depth(depth)
    color = rng.random((layers, 6, res, res, 3)).astype(np.float32)
    return q, surface, color, bases


def test_search_matches_naive_twin():
    rng = np.random.default_rng(1)
    for layers in (1, 2):
        q, surface, color, bases = _box_map(layers=layers, seed=layers)
        texels = search_texels(q, surface)
        out = np.zeros(3, np.float32)
        agree = 0
        for trial in range(300):
            x = rng.uniform(-1.5, 1.5, 3)
            r = rng.normal(size=3)
            r /= np.linalg.norm(r)
            if trial < 6:  # edge cases: rays along the axes and through face corners
                r = np.eye(3)[trial % 3] * (1 if trial < 3 else -1)
            a = max(np.linalg.norm(x), 0.05)
            t_end = 40.0 / (40.0 + a)
            steps, refine = int(rng.integers(1, 24)), int(rng.integers(0, 6))
            hit, _ = search_ray(x[0], x[1], x[2], r[0], r[1], r[2], a, t_end, *texels,
                                color, bases, steps, refine, True, out, _search_work(layers))
            n_hit, n_color = naive_search(x, r, a, t_end, q, surface, color, steps, refine)
            assert bool(hit) == n_hit, (trial, layers)
            if hit:
                np.testing.assert_allclose(out, n_color, atol=2e-5)
                agree += 1
        assert agree > 150


def test_box_room_hit_is_exact_on_planes():
    """One wall per face, no blocks: a secant step lands on the plane; the colour read is
    the bilinear colour at the exact hit direction."""
    q, surface, color, bases = _box_map(res=32, layers=1)
    out = np.zeros(3, np.float32)
    x = np.array([0.3, -0.2, 0.5])
    r = np.array([0.6, 0.3, -0.74])
    r /= np.linalg.norm(r)
    a = np.linalg.norm(x)
    hit, _ = search_ray(*x, *r, a, 40.0 / (40.0 + a), *search_texels(q, surface), color, bases,
                        8, 3, True, out, _search_work(1))
    d = min((4.0 - np.sign(r[i]) * x[i]) / abs(r[i]) for i in range(3))
    face, s, t = face_uv(x + d * r)
    from naive import bilinear
    assert hit
    np.testing.assert_allclose(out, bilinear(color[0, face], s, t), atol=1e-5)


def test_update_policies():
    assert face_capture_frames(17, "once") == [0] * 6
    assert face_capture_frames(17, "every") == [17] * 6
    assert face_capture_frames(17, 4) == [16] * 6
    assert map_capture_frame(17, 4) == 16 and map_capture_frame(3, "once") == 0
    # one face a frame, round robin: frame 7 refreshes face 1, frame 6 face 0, ...
    assert face_capture_frames(7, "every", 1) == [6, 7, 2, 3, 4, 5]
    assert face_capture_frames(2, "every", 2) == [0, 0, 1, 1, 2, 2]
    assert [faces_updated(i, "every", 2) for i in range(4)] == [6, 2, 2, 2]
    assert [faces_updated(i, 3) for i in range(7)] == [6, 0, 0, 6, 0, 0, 6]


def test_depth_peeling_layers(tmp_path):
    """Layer k holds the k-th surface along each texel's center ray."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from conftest import SCENES

    from reflectcli.loading import load_config
    from reflectcli.raster.rasterize import FLAG_MIRROR
    from reflectcli.scene.build import build_scene

    path = SCENES / "l-room.toml"
    cfg, _ = load_config(str(path), [], None)
    scene = build_scene(cfg, str(path))
    tris = scene.geometry(0).all_triangles()
    flags = np.where(tris.surface >= scene.n_objects, FLAG_MIRROR, 0).astype(np.uint8)
    point = np.array([-0.9, 1.3, -0.9])
    color, depth, surf = capture_distance_faces(scene, tris, flags, point, 16, 3,
                                                scene.n_objects, 0.01, 100.0)
    finite = np.isfinite(depth)
    assert finite[0].all()  # a closed room: every direction sees something
    both = finite[1:] & finite[:-1]
    assert (depth[1:][both] > depth[:-1][both]).all()  # strictly peeled (finite pairs only)
    assert not (finite[1:] & ~finite[:-1]).any()  # nothing after an empty layer
    # the pedestal hides the north/west walls: some texels see it first, the wall later
    pedestal = scene.surface_names.index("pedestal")
    behind = surf[1][surf[0] == pedestal]
    # (a texel on the edge where the pedestal stands on the floor peels all three at once)
    assert behind.size > 0 and (behind >= 0).mean() > 0.95


def test_reflected_ray_matches_twin():
    """The reflected ray of a reflector pixel, for each reflector kind, on random triangles."""
    from naive import reflected_ray

    from reflectcli.reflection import reflected_ray as mirror_ray
    from reflectcli.scene.types import CYLINDER, MESH, PLANAR, SPHERE

    rng = np.random.default_rng(3)
    corners = rng.normal(size=(8, 3, 3)).astype(np.float32)
    normals = rng.normal(size=(8, 3, 3)).astype(np.float32)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    plane_n = rng.normal(size=3)
    plane_n /= np.linalg.norm(plane_n)
    params = {PLANAR: np.r_[plane_n, 0.3, np.zeros(4)],
              SPHERE: np.r_[rng.normal(size=3), 1.0, np.zeros(4)],
              CYLINDER: np.r_[rng.normal(size=3), axis, 0.0, 0.0],
              MESH: np.zeros(8)}  # a mesh: interpolated normals
    for kind, p in params.items():
        p = p.astype(np.float32)
        for t in range(8):
            b1, b2 = rng.random(2) * 0.5
            eye = (rng.normal(size=3) * 5).astype(np.float32)
            got = mirror_ray(t, np.float32(b1), np.float32(b2), corners, normals, kind, p, eye)
            point, r = reflected_ray(t, b1, b2, corners, normals, kind, p, eye)
            np.testing.assert_allclose(got[:3], point, atol=1e-5)
            np.testing.assert_allclose(got[3:6], r, atol=1e-4)
            # n.v, the cosine of incidence (the normal turned toward the eye): r.v
            v = eye - point
            np.testing.assert_allclose(got[6], np.sqrt((1.0 + r @ (v / np.linalg.norm(v))) / 2),
                                       atol=1e-4)
