"""Explosion maps (layers, the maps built for their lookups, fills, nearest fill,
lookups) against their slow twins."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from naive import (
    explosion_virtual,
    fill_extensions,
    fill_faces,
    fill_triangle,
    fused_multiply_add,
    map_coords,
    nearest_filled_distance,
    nearest_filled_texel,
    part_extent,
    plane_from_map,
    ray_focus,
    screen_from_world,
    screen_plane,
    setup_arrays,
    vertex_coords,
)

from reflectcli.scene import primitives
from reflectcli.virtual import explosion, mapfill
from reflectcli.virtual.mesh import weld


@pytest.fixture(scope="module")
def sphere_maps():
    m = primitives.uv_sphere(1.0, 12)
    mesh = weld(m.corners, m.normals)
    eye = np.array([0.4, 1.0, 6.0])
    return mesh, eye, explosion.build_explosion_maps(mesh, eye, np.zeros(3), 1.1, 30.0, 48,
                                                     layers=3)


def _einsum_sums_as_the_kernels_do() -> bool:
    """Whether this machine's numpy takes np.einsum("ij,ij->i")'s three-term dot products
    as (x0 y0 + x2 y2) + x1 y1 and einsum("kij,kj->i") row by row so (its SIMD loops do,
    on this machine kind): the order the set-up kernels reproduce. Elsewhere they match
    numpy to rounding only."""
    rng = np.random.default_rng(3)
    x, y = rng.normal(size=(256, 3)), rng.normal(size=(256, 3))
    pairs = np.einsum("ij,ij->i", x, y)
    p, v = rng.normal(size=(64, 3, 3)), rng.normal(size=(64, 3))
    rows = np.zeros(3)
    for k in range(64):
        rows += (p[k, :, 0] * v[k, 0] + p[k, :, 2] * v[k, 2]) + p[k, :, 1] * v[k, 1]
    return bool((pairs == (x[:, 0] * y[:, 0] + x[:, 2] * y[:, 2]) + x[:, 1] * y[:, 1]).all()
                and (np.einsum("kij,kj->i", p, v) == rows).all())


def _same(got: np.ndarray, want: np.ndarray, bits: bool) -> None:
    assert got.dtype == want.dtype and got.shape == want.shape
    if bits:
        assert got.tobytes() == want.tobytes()
    else:
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


@pytest.fixture(scope="module")
def part_meshes():
    """(meshes, eyes): two spheres and the mask's 14 parts (convex, concave, open, with
    boundary edges), its camera's eye and six eyes around them."""
    from conftest import open_scene

    rng = np.random.default_rng(7)
    meshes = [weld(m.corners, m.normals) for m in (primitives.uv_sphere(1.0, 12),
                                                   primitives.uv_sphere(0.7, 24))]
    opened = open_scene("mask", "virtual", ["camera.width=64", "camera.height=64"])
    state = opened.prepare()
    meshes += [part.mesh for shape in state.shapes.entries.values() for part in shape.parts]
    assert len(meshes) > 10
    return meshes, [opened.camera(0).eye] + [rng.normal(0.0, 3.0, 3) for _ in range(6)]


def test_ray_focus_matches_twin_bit_for_bit(part_meshes):
    """ray_focus's sums in a kernel (_focus_sums) give the numbers of the whole-array numpy
    twin bit for bit, so the map centre, the maps and the seeds do not move: spheres and
    the mask's parts from eyes around them, and a mesh turned away (fewer than three front
    vertices: the vertex mean)."""
    meshes, eyes = part_meshes
    bits = _einsum_sums_as_the_kernels_do()
    for mesh in meshes:
        for eye in eyes:
            _same(explosion.ray_focus(mesh, eye), ray_focus(mesh.vertices, mesh.normals, eye),
                  bits)
    # every normal turned from the eye: no front vertex, the vertex mean
    sphere, eye = meshes[0], eyes[0]
    away = sphere.vertices - eye
    away /= np.linalg.norm(away, axis=1, keepdims=True)
    turned = dataclasses.replace(sphere, normals=away)
    assert explosion.ray_focus(turned, eye).tobytes() == sphere.vertices.mean(axis=0).tobytes()


def test_map_setup_arrays_match_twin_bit_for_bit(part_meshes):
    """map_setup's per-vertex and per-face arrays in a kernel (_setup_arrays) are the
    whole-array numpy twin's bit for bit (fixed normals, front, used, drawn faces,
    extensions): spheres seen from outside (profile faces, two-back extensions) and the
    mask's open parts (boundary edges), from eyes around them."""
    from reflectcli.virtual.explosion import boundary_edges

    meshes, eyes = part_meshes
    bits = _einsum_sums_as_the_kernels_do()
    extended = 0
    for mesh in meshes:
        boundary = boundary_edges(mesh.faces)
        for eye in eyes:
            got = explosion._setup_arrays(mesh.vertices, mesh.normals, mesh.faces,
                                          boundary.reshape(-1, 3), eye)
            want = setup_arrays(mesh.vertices, mesh.normals, mesh.faces,
                                boundary.reshape(-1, 3), eye)
            for g, w in zip(got, want, strict=True):
                _same(g, w, bits or g.dtype != np.float64)
            extended += len(got[4])
    assert extended > 0


@pytest.mark.parametrize("layers", [2, 5])
def test_explosion_layers_match_twin(layers):
    """_build_layers (every layer at once, a layer per thread) against the twins of its
    steps layer by layer: vertex coordinates, faces, the tally inside the circle, the
    extensions, and for each texel left empty an id of a filled texel at the nearest
    distance (ties between equally near ones are the transform's to break), unless no
    texel a lookup can reach was left empty (then the fill is skipped)."""
    m = primitives.uv_sphere(1.0, 10)
    mesh = weld(m.corners[:150], m.normals[:150])  # open: boundary edges give extensions
    eye = np.array([0.4, 1.0, 6.0])
    maps = explosion.build_explosion_maps(mesh, eye, np.zeros(3), 1.1, 30.0, 40, layers)
    assert len(maps.extensions)
    res, s = maps.res, maps.s
    c = np.arange(res) + 0.5 - res / 2.0
    circle_in = (c[None, :] ** 2 + c[:, None] ** 2) <= (s / 2.0) ** 2
    used = ~np.isnan(maps.layers[0].coords[:, 0])
    drawn = np.flatnonzero(used[mesh.faces].all(axis=1)
                           & (maps.front[mesh.faces].any(axis=1)))
    for layer in maps.layers:
        coords = vertex_coords(mesh.vertices, maps.normals, used, eye, maps.center,
                               layer.radius, maps.frame, res, s)
        np.testing.assert_allclose(layer.coords, coords, rtol=1e-12, atol=1e-9)
        ids = np.full((res, res), -1, np.int32)
        fill_faces(ids, layer.coords, mesh.faces, drawn)
        np.testing.assert_array_equal(layer.core, ids >= 0)
        assert layer.filled_before_extension == int(((ids >= 0) & circle_in).sum())
        fill_extensions(ids, layer.coords, maps.extensions, len(mesh.faces), res / 2.0,
                        explosion.EXTENSION_REACH * s)
        empty = ids < 0
        assert layer.empty_after_extension == int((empty & circle_in).sum())
        np.testing.assert_array_equal(layer.ids[~empty], ids[~empty])
        # texels a lookup can land in: their squares meet the disk of radius s / 2
        g = np.maximum(np.abs(c) - 0.5, 0.0)
        reachable = (g[None, :] ** 2 + g[:, None] ** 2) <= (s / 2.0 + 1e-6) ** 2
        if not (empty & reachable).any():
            continue  # nothing a lookup reaches is empty: the fill is skipped
        dist = nearest_filled_distance(empty)
        fy, fx = np.nonzero(~empty)
        for y, x in zip(*np.nonzero(empty), strict=True):
            near = (fy - y) ** 2 + (fx - x) ** 2 == round(dist[y, x] ** 2)
            assert layer.ids[y, x] in set(ids[fy[near], fx[near]]), (y, x)


def test_maps_for_lookups_of_a_patch_seen_from_behind():
    """A patch facing away from the eye fills no texel of any layer: built for lookups
    spread over a 200^2 map (the grown box the whole map), the build returns (the search
    for a nearest filled texel once never ended here) with the whole build's ids."""
    corners = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]],
                        [[1, 0, 0], [1, 1, 0], [0, 1, 0]]], float)
    normals = np.zeros_like(corners)
    normals[..., 2] = -1.0  # facing away from the eye at z = 6
    mesh = weld(corners, normals)
    eye, center = np.array([0.4, 1.0, 6.0]), np.array([0.5, 0.5, 0.0])
    pts = np.random.default_rng(0).normal(size=(200, 3)) * 3.0 + [0.5, 0.5, 4.0]
    whole = explosion.build_explosion_maps(mesh, eye, center, 0.5, 5.0, 200)
    some = explosion.build_explosion_maps(mesh, eye, center, 0.5, 5.0, 200, lookups=pts)
    for a, b in zip(whole.layers, some.layers, strict=True):
        assert (a.ids < 0).all() and (b.ids < 0).all()


@pytest.mark.parametrize("open_mesh", [False, True])
def test_maps_built_for_their_lookups_match_whole_maps_there(open_mesh):
    """build_explosion_maps with `lookups`: at every texel those points are looked up at
    (layers lo and lo + 1 of each, found by the twins' map_coords and radii), the ids and
    core of the whole build, and the same virtual vertices, bit for bit; on a closed
    sphere (extensions close the circle) and an open patch off the map's center (its
    extensions leave texels empty that lookups land in: the fill runs), points near and
    far, some flipped."""
    if open_mesh:
        corners = np.array([[[2, 0, 0], [2.5, 0, 0], [2.5, 0.5, 0]],
                            [[2, 0, 0], [2.5, 0.5, 0], [2, 0.5, 0]]], float)
        normals = np.zeros_like(corners)
        normals[..., 2] = 1.0
        normals[0, 0] = [0.3, 0.0, 1.0]  # a bend, so the patch's image is not a line
        normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    else:
        m = primitives.uv_sphere(1.0, 10)
        corners, normals = m.corners, m.normals
    mesh = weld(corners, normals)
    eye = np.array([0.4, 1.0, 6.0])
    rng = np.random.default_rng(12)
    pts = np.concatenate([rng.normal(size=(40, 3)) * 4.0,
                          [0.0, 0.0, 3.0] + rng.normal(size=(20, 3)) * 0.3])
    for flip_axis in (None, np.array([0.0, 0.0, 1.0])):
        whole = explosion.build_explosion_maps(mesh, eye, np.zeros(3), 1.1, 30.0, 40, 4)
        some = explosion.build_explosion_maps(mesh, eye, np.zeros(3), 1.1, 30.0, 40, 4,
                                              lookups=pts, flip_axis=flip_axis)
        radii = np.array([layer.radius for layer in whole.layers])
        flip = np.zeros(3) if flip_axis is None else flip_axis
        marked = np.zeros((len(radii), 40, 40), bool)
        for p in pts:
            d = p - whole.center
            d = -d if d @ flip < 0 else d
            tx, ty = map_coords(whole.frame, whole.res, whole.s, d)
            dist = np.linalg.norm(p - whole.center)
            lo = min(int(np.searchsorted(radii[1:], dist)), len(radii) - 2)
            x, y = (min(max(int(np.floor(t)), 0), 39) for t in (tx, ty))
            marked[[lo, lo + 1], y, x] = True
        for k, (a, b) in enumerate(zip(whole.layers, some.layers, strict=True)):
            np.testing.assert_array_equal(a.ids[marked[k]], b.ids[marked[k]])
            np.testing.assert_array_equal(a.core[marked[k]], b.core[marked[k]])
            np.testing.assert_array_equal(a.coords, b.coords)
        if open_mesh:  # a lookup lands where faces and extensions leave a texel empty
            used = ~np.isnan(whole.layers[0].coords[:, 0])
            drawn = np.flatnonzero(used[mesh.faces].all(axis=1)
                                   & whole.front[mesh.faces].any(axis=1))
            holes = False
            for k, layer in enumerate(whole.layers):
                ids = np.full((40, 40), -1, np.int32)
                fill_faces(ids, layer.coords, mesh.faces, drawn)
                fill_extensions(ids, layer.coords, whole.extensions, len(mesh.faces), 20.0,
                                explosion.EXTENSION_REACH * whole.s)
                holes |= bool((ids[marked[k]] < 0).any())
            assert holes
        none = np.full(len(pts), -1)
        got = explosion.virtual_vertices(some, pts, none, np.zeros((len(pts), 2)),
                                         np.zeros((len(mesh.vertices), 2)), flip_axis)
        want = explosion.virtual_vertices(whole, pts, none, np.zeros((len(pts), 2)),
                                          np.zeros((len(mesh.vertices), 2)), flip_axis)
        assert got[0].tobytes() == want[0].tobytes()
        np.testing.assert_array_equal(got[1], want[1])


def test_map_coords_and_vertex_coords_match_twin(sphere_maps):
    mesh, eye, maps = sphere_maps
    rng = np.random.default_rng(4)
    for d in list(rng.normal(size=(100, 3))) + [maps.frame[2], maps.frame[0]]:  # not -z: the rim
        np.testing.assert_allclose(explosion.map_coords(maps.frame, maps.res, maps.s, *d),
                                   map_coords(maps.frame, maps.res, maps.s, d), atol=1e-9)
    for layer in maps.layers:
        used = ~np.isnan(layer.coords[:, 0])
        assert 0 < used.sum() < len(used)
        want = vertex_coords(mesh.vertices, maps.normals, used, eye, maps.center,
                             layer.radius, maps.frame, maps.res, maps.s)
        np.testing.assert_allclose(layer.coords, want, atol=1e-9)
    # the kernel's own order of operations, one vertex at a time in Python floats (the bits
    # of the scalar kernel it replaced), some vertices unused: NaN there
    used = rng.random(len(mesh.vertices)) < 0.7
    for radius in (1.1, 4.0, 30.0):
        got = np.empty((len(mesh.vertices), 2))
        explosion._vertex_coords(mesh.vertices, maps.normals, used, eye, maps.center, radius,
                                 maps.frame, maps.res, maps.s, got)
        want = np.full_like(got, np.nan)
        f, c, half = maps.frame, maps.center, maps.res / 2.0
        for i in np.flatnonzero(used):
            (vx, vy, vz), (nx, ny, nz) = mesh.vertices[i].tolist(), maps.normals[i].tolist()
            dx, dy, dz = vx - eye[0], vy - eye[1], vz - eye[2]
            inv = 1.0 / math.sqrt(dx * dx + dy * dy + dz * dz)
            dx, dy, dz = dx * inv, dy * inv, dz * inv
            dn = dx * nx + dy * ny + dz * nz
            rx, ry, rz = dx - 2 * dn * nx, dy - 2 * dn * ny, dz - 2 * dn * nz
            ox, oy, oz = vx - c[0], vy - c[1], vz - c[2]
            b = ox * rx + oy * ry + oz * rz
            t = -b + math.sqrt(max(b * b - (ox * ox + oy * oy + oz * oz - radius * radius),
                                   0.0))
            hx, hy, hz = ox + t * rx, oy + t * ry, oz + t * rz
            length = math.sqrt(hx * hx + hy * hy + hz * hz)
            x = (f[0, 0] * hx + f[0, 1] * hy + f[0, 2] * hz) / length
            y = (f[1, 0] * hx + f[1, 1] * hy + f[1, 2] * hz) / length
            z = (f[2, 0] * hx + f[2, 1] * hy + f[2, 2] * hz) / length
            m = 2.0 * math.sqrt(max(2.0 * (z + 1.0), 1e-24))
            want[i] = maps.s * x / m + half, maps.s * y / m + half
        assert got.tobytes() == want.tobytes()


def test_fill_kernels_match_twin(sphere_maps):
    mesh, _, maps = sphere_maps
    rng = np.random.default_rng(5)
    for _ in range(40):  # single triangles, both windings, some degenerate or NaN
        tri = rng.uniform(-5, 30, (3, 2))
        if rng.random() < 0.1:
            tri[2] = tri[0] + 0.5 * (tri[1] - tri[0])
        if rng.random() < 0.05:
            tri[1, 0] = np.nan
        only_empty = bool(rng.random() < 0.5)
        ids = np.where(rng.random((24, 24)) < 0.3, 7, -1).astype(np.int32)
        want = ids.copy()
        mapfill._fill_triangle(ids, *tri.reshape(-1), 3, only_empty)
        fill_triangle(want, *tri, 3, only_empty)
        np.testing.assert_array_equal(ids, want)
    # edges through texel centers and nearly level or upright ones (slopes about the 1e-3
    # below which an edge does not narrow a row's span: _spare), long thin slivers: the
    # spans' small spare must keep every texel the tests pass
    for i in range(300):
        a = np.floor(rng.uniform(0, 24, 2)) + 0.5
        b = a + rng.uniform(-20, 20, 2)
        if i % 3 == 0:
            b[1] = a[1] + rng.choice([0.0, 1e-3, -1e-3, 2e-3, 0.5e-3, 1e-9]) * (b[0] - a[0])
        elif i % 3 == 1:
            b[0] = a[0] + rng.choice([0.0, 1e-3, -1e-3, 1e-9]) * (b[1] - a[1])
        c = a + (b - a) * rng.uniform(0, 1) + rng.choice([1e-3, 0.02, 0.3, 3.0]) * \
            rng.normal(size=2)
        if i % 5 == 0:
            c = np.floor(c) + 0.5
        tri = rng.permutation(np.array([a, b, c]))
        ids = np.where(rng.random((24, 24)) < 0.3, 7, -1).astype(np.int32)
        want = ids.copy()
        only_empty = bool(i % 2)
        mapfill._fill_triangle(ids, *tri.reshape(-1), 3, only_empty)
        fill_triangle(want, *tri, 3, only_empty)
        np.testing.assert_array_equal(ids, want)
    layer = maps.layers[1]
    f = mesh.faces
    drawn = rng.permutation(len(f))[: len(f) // 2].astype(np.int64)
    ids = np.full((maps.res, maps.res), -1, np.int32)
    want = ids.copy()
    explosion._fill_faces(ids, layer.coords, f, drawn)
    fill_faces(want, layer.coords, f, drawn)
    np.testing.assert_array_equal(ids, want)
    half = maps.res / 2.0
    explosion._fill_extensions(ids, layer.coords, maps.extensions, len(f), half,
                               explosion.EXTENSION_REACH * maps.s)
    fill_extensions(want, layer.coords, maps.extensions, len(f), half,
                    explosion.EXTENSION_REACH * maps.s)
    np.testing.assert_array_equal(ids, want)
    assert (ids >= len(f)).any()


def test_ids_at_marked_texels_match_the_fill_twins(sphere_maps):
    """mapfill._ids_at_marked (faces and quads sorted into cells, each marked texel tested
    alone) against drawing the whole map with the fill twins: at every marked texel the
    same id (the last face holding it, else the first quad) and core (a face holds it);
    True exactly when no marked texel is left empty. On the sphere's maps, with extra
    degenerate, NaN, tiny and map-wide triangles and quads, texels marked scattered, in
    clusters and on the map's edges, inside boxes of several sizes."""
    mesh, _, maps = sphere_maps
    rng = np.random.default_rng(8)
    res, half = maps.res, maps.res / 2.0
    reach = explosion.EXTENSION_REACH * maps.s
    for case in range(12):
        layer = maps.layers[case % len(maps.layers)]
        coords = layer.coords.copy()
        extra = np.concatenate([rng.uniform(-10, res + 10, (20, 2)),
                                coords[:5] + rng.normal(size=(5, 2)) * 0.3])
        extra[3] = np.nan
        # small triangles (at most _SMALL texels visited) over the large ones, drawn in
        # between them: _ids_at_marked tests those at once, the others through cells;
        # clustered, so that several hold one texel (the last drawn must win), a third of
        # their corners on texel centres (edges through centres: the >= of the tests)
        clusters = rng.uniform(4, res - 4, (4, 2))
        small = (clusters[rng.integers(0, 4, 40)][:, None, :]
                 + rng.normal(size=(40, 3, 2)) * 0.9)
        small[::3] = np.floor(small[::3]) + 0.5
        coords = np.concatenate([coords, extra, small.reshape(-1, 2)])
        v = len(layer.coords)
        w = v + len(extra)
        faces = np.concatenate([mesh.faces, rng.integers(0, len(coords), (30, 3)),
                                [[v, v, v + 1], [v + 3, v + 4, v + 5]],
                                w + np.arange(120).reshape(40, 3)]).astype(np.int64)
        drawn = rng.permutation(len(faces))[: int(len(faces) * rng.uniform(0.3, 1.0))]
        extensions = np.concatenate([maps.extensions, np.column_stack(
            [np.zeros(15, np.int64), rng.integers(0, len(coords), (15, 2))])])
        marks = rng.random((res, res)) < rng.choice([0.002, 0.02, 0.2])
        marks[rng.integers(0, res - 6):, :3] = True  # an edge, a cluster
        marks[0, rng.integers(0, res)] = True
        for cy, cx in clusters.astype(int):  # the clusters' texels looked up
            marks[cy - 3:cy + 4, cx - 3:cx + 4] = True
        y0, y1, x0, x1 = mapfill._marked_box(marks)
        ids = np.full((res, res), -1, np.int32)
        core = np.zeros((res, res), bool)
        # the texels listed as lookups list them: in any order, some several times
        texels = mapfill._marked_texels(marks, y0, y1, x0, x1)
        if case % 2:
            texels = np.concatenate([texels, texels[rng.integers(0, len(texels), 50)]])
            texels = np.ascontiguousarray(texels[rng.permutation(len(texels))])
        full = mapfill._ids_at_marked(ids, core, marks, coords, faces, drawn, extensions,
                                      len(faces), half, reach, y0, y1, x0, x1, texels)
        want = np.full((res, res), -1, np.int32)
        fill_faces(want, coords, faces, drawn)
        want_core = want >= 0
        fill_extensions(want, coords, extensions, len(faces), half, reach)
        np.testing.assert_array_equal(ids[marks], want[marks])
        np.testing.assert_array_equal(core[marks], want_core[marks])
        assert (ids[~marks] == -1).all() and not core[~marks].any()
        assert full == bool((want[marks] >= 0).all())
        filled = marks & (want >= 0)  # only filled texels marked: none left empty
        again = np.full((res, res), -1, np.int32)
        box = mapfill._marked_box(filled)
        assert mapfill._ids_at_marked(again, core, filled, coords, faces, drawn, extensions,
                                      len(faces), half, reach, *box,
                                      mapfill._marked_texels(filled, *box))
        np.testing.assert_array_equal(again[filled], want[filled])
        # the holes' box as _build_layer takes it from _holes (rows in order)
        holes, _ = mapfill._holes(ids, marks, np.ones_like(marks), y0, y1, x0, x1)
        empty = np.argwhere(marks & (ids < 0))
        if len(empty):
            hole = (holes[0, 0], holes[-1, 0], holes[:, 1].min(), holes[:, 1].max())
            assert hole == (empty[:, 0].min(), empty[:, 0].max(), empty[:, 1].min(),
                            empty[:, 1].max())
        else:
            assert len(holes) == 0


def test_ids_at_marked_leave_marks_outside_their_box(sphere_maps):
    """_ids_at_marked given a box smaller than its marks: the marked texels inside the box
    get the fill twins' ids, the marks outside it stay untouched, and True means that every
    marked texel inside the box is filled (not those outside)."""
    mesh, _, maps = sphere_maps
    rng = np.random.default_rng(9)
    res, half = maps.res, maps.res / 2.0
    reach = explosion.EXTENSION_REACH * maps.s
    layer = maps.layers[0]
    faces = np.ascontiguousarray(mesh.faces, np.int64)
    drawn = np.arange(len(faces))
    want = np.full((res, res), -1, np.int32)
    fill_faces(want, layer.coords, faces, drawn)
    want_core = want >= 0
    fill_extensions(want, layer.coords, maps.extensions, len(faces), half, reach)
    for case in range(6):
        marks = rng.random((res, res)) < 0.05
        marks[0, :] = marks[:, 0] = marks[-1, :] = marks[:, -1] = True
        if case % 2:  # every marked texel inside the box filled, some outside it not
            marks &= want >= 0
            marks[0, 0] = marks[-1, -1] = True
        y0, x0 = rng.integers(1, res // 3, 2)
        y1, x1 = rng.integers(2 * res // 3, res - 1, 2)
        box = np.zeros((res, res), bool)
        box[y0:y1 + 1, x0:x1 + 1] = True
        ids = np.full((res, res), -7, np.int32)
        core = np.zeros((res, res), bool)
        full = mapfill._ids_at_marked(ids, core, marks, layer.coords, faces, drawn,
                                      maps.extensions, len(faces), half, reach, y0, y1, x0,
                                      x1, mapfill._marked_texels(marks, y0, y1, x0, x1))
        inside = marks & box
        np.testing.assert_array_equal(ids[inside], want[inside])
        np.testing.assert_array_equal(core[inside], want_core[inside])
        assert (ids[~inside] == -7).all() and not core[~inside].any()
        assert full == bool((want[inside] >= 0).all())
        if case % 2:
            assert full and not (want[marks & ~box] >= 0).all()


def test_plane_and_screen_lookups_match_twin(sphere_maps):
    mesh, _, maps = sphere_maps
    rng = np.random.default_rng(6)
    layer = maps.layers[0]
    ids = layer.ids.copy()
    ids[:2] = -1  # some empty texels
    for t in list(rng.uniform(-2, maps.res + 2, (300, 2))):
        p, n = explosion._plane_from_map(ids, layer.coords, mesh.vertices, maps.normals,
                                         mesh.faces, maps.extensions, *t)
        wp, wn = plane_from_map(ids, layer.coords, mesh.vertices, maps.normals, mesh.faces,
                                maps.extensions, t)
        np.testing.assert_allclose(p, wp, atol=1e-8)
        np.testing.assert_allclose(n, wn, atol=1e-8)
    screen = rng.uniform(0, 50, (len(mesh.vertices), 2))
    screen[mesh.faces[0, 2]] = screen[mesh.faces[0, 0]]  # a degenerate face on screen
    for f in list(rng.integers(0, len(mesh.faces), 100)) + [0]:
        s = rng.uniform(0, 50, 2)
        p, n = explosion._screen_plane(mesh.faces, f, screen, mesh.vertices, maps.normals, *s)
        wp, wn = screen_plane(mesh.faces, f, screen, mesh.vertices, maps.normals, s)
        np.testing.assert_allclose(p, wp, atol=1e-8, rtol=1e-8)
        np.testing.assert_allclose(n, wn, atol=1e-8)


@pytest.mark.parametrize("flip", [False, True])
def test_explosion_lookup_matches_twin(sphere_maps, flip):
    mesh, eye, maps = sphere_maps
    rng = np.random.default_rng(7)
    n = 200
    pts = rng.normal(size=(n, 3)) * 4.0
    pts[:3] = [[0.0, 0.0, 40.0], [0.0, 0.0, 1.05], [0.5, 0.5, 0.0]]  # beyond far, near, inside
    hidden_face = np.where(rng.random(n) < 0.2, rng.integers(0, len(mesh.faces), n), -1)
    hidden_screen = rng.uniform(0, 50, (n, 2))
    screen = rng.uniform(0, 50, (len(mesh.vertices), 2))
    flip_axis = np.array([0.0, 0.0, 1.0]) if flip else None
    got, flags = explosion.virtual_vertices(maps, pts, hidden_face, hidden_screen, screen,
                                            flip_axis)
    ids = np.stack([layer.ids for layer in maps.layers])
    want, unreflected = explosion_virtual(
        pts, mesh.vertices, maps.normals, mesh.faces, maps.extensions, ids,
        np.stack([layer.coords for layer in maps.layers]),
        np.array([layer.radius for layer in maps.layers]), maps.center,
        np.zeros(3) if flip_axis is None else flip_axis, maps.frame, maps.res, maps.s,
        hidden_face, hidden_screen, screen, np.stack([layer.core for layer in maps.layers]))
    np.testing.assert_allclose(got, want, atol=1e-8, rtol=1e-9)
    np.testing.assert_array_equal(flags, (hidden_face >= 0) | unreflected)
    assert not unreflected.all() and (unreflected.any() or flip)


def test_nearest_filled_matches_twin():
    """The feature transform behind _fill_nearest names, for every texel, a filled texel at
    the least distance (ties may go either way), on sparse, dense, one-row and one-column
    maps and a map with one filled texel."""
    rng = np.random.default_rng(8)
    cases = [rng.random(tuple(rng.integers(1, 30, 2))) < p for p in (0.3, 0.8, 0.97)
             for _ in range(10)]
    cases += [rng.random((1, 25)) < 0.7, rng.random((25, 1)) < 0.7,
              np.arange(400).reshape(20, 20) != 137]
    for empty in cases:
        if empty.all():
            continue
        h, w = empty.shape
        rows = np.empty((h, w), np.int32)
        cols = np.empty((h, w), np.int32)
        explosion._nearest_filled(empty, rows, cols)
        assert not empty[rows, cols].any()
        got = np.hypot(rows - np.arange(h)[:, None], cols - np.arange(w)[None, :])
        np.testing.assert_allclose(got, nearest_filled_distance(empty), rtol=0, atol=1e-12)


def test_holes_are_the_marked_empty_texels_of_the_box():
    """_holes lists the marked empty texels of a box in row order, or none and False where
    one lies outside `reach` (the whole layer's build then takes over)."""
    rng = np.random.default_rng(13)
    for _ in range(60):
        h, w = (int(v) for v in rng.integers(8, 40, 2))
        layer = np.where(rng.random((h, w)) < rng.choice([0.02, 0.1, 0.5]),
                         rng.integers(0, 50, (h, w)), -1).astype(np.int32)
        y0, x0 = int(rng.integers(0, h)), int(rng.integers(0, w))
        y1, x1 = int(rng.integers(y0, h)), int(rng.integers(x0, w))
        marks = rng.random((h, w)) < 0.2
        reach = rng.random((h, w)) < 0.97
        holes, reached = mapfill._holes(layer, marks, reach, y0, y1, x0, x1)
        box = np.zeros((h, w), bool)
        box[y0:y1 + 1, x0:x1 + 1] = True
        sel = marks & box & (layer < 0)
        assert reached == bool(reach[sel].all())
        if reached:
            assert holes.tolist() == np.argwhere(sel).tolist()


def _hole_fills(rng, want, table, n_drawn, densities=(0.002, 0.01, 0.04)):
    """_fill_holes over a layer's triangle table (_layer_triangles) against the whole layer
    `want` (the fill twins' faces and quads) and its nearest fill (nearest_filled_texel):
    random marked texels hold want's ids (as _ids_at_marked leaves them), the other texels
    stale; each hole (a marked texel want leaves empty) must take the id of its nearest
    filled texel by the whole map's rule, every other texel untouched. Some cases mark
    holes alone (no looked-up texel filled to bound the search). Returns the holes
    checked."""
    res = want.shape[0]
    checked = 0
    empty = np.argwhere(want < 0)
    for density in densities:
        for mode in ("some", "alone", "pairs"):
            marks = rng.random((res, res)) < density
            if mode == "alone":
                marks &= want < 0
            elif mode == "pairs" and (want >= 0).any() and len(empty):
                # a hole or two and, of their nearest filled texels, the one the rule takes
                # last alone: the searches' bounds are as near as their answers, which lie
                # on the edge of the cells' box (or tie with them)
                marks[:] = False
                fy, fx = np.nonzero(want >= 0)
                for y, x in empty[rng.permutation(len(empty))[:2]]:
                    d2 = (fy - y) ** 2 + (fx - x) ** 2
                    tied = np.flatnonzero(d2 == d2.min())
                    last = max(tied, key=lambda i: (fx[i], fy[i]))
                    marks[y, x] = marks[fy[last], fx[last]] = True
            if not (marks & (want < 0)).any():
                continue
            ids = np.where(marks, want, rng.integers(-3, 40, (res, res))).astype(np.int32)
            stale = ids.copy()
            texels = np.argwhere(marks).astype(np.int64)
            texels = np.concatenate([texels, texels[:3]])  # repeats, in any order
            texels = texels[rng.permutation(len(texels))]
            holes = np.argwhere(marks & (want < 0)).astype(np.int64)
            ok = mapfill._fill_holes(ids, texels, holes, *table, n_drawn)
            if not ok:  # nothing filled, or too long a search: the whole layer's, unwritten
                np.testing.assert_array_equal(ids, stale)
                assert not (want >= 0).any() or len(holes) * len(texels) > res * res or \
                    len(holes) > 20
                continue
            expect = stale.copy()
            for y, x in holes:
                ny, nx = nearest_filled_texel(want, y, x)
                expect[y, x] = want[ny, nx]
            np.testing.assert_array_equal(ids, expect)
            checked += len(holes)
    return checked


def test_hole_fill_matches_the_whole_layer_s_nearest_fill(sphere_maps):
    """_fill_holes (each hole's nearest filled texel from the layer's triangles, without
    drawing) against the fill twins' whole layer and the whole map's nearest rule, on the
    sphere's layers with some faces not drawn (holes inside the disk) and with degenerate,
    NaN, tiny, map-wide and off-map triangles and quads among them."""
    mesh, _, maps = sphere_maps
    rng = np.random.default_rng(23)
    res, half = maps.res, maps.res / 2.0
    reach = explosion.EXTENSION_REACH * maps.s
    checked = 0
    for case in range(12):
        layer = maps.layers[case % len(maps.layers)]
        faces = np.ascontiguousarray(mesh.faces, np.int64)
        coords, extensions = layer.coords, maps.extensions
        if case >= 2:
            extra = np.concatenate([rng.uniform(-30, res + 30, (20, 2)),
                                    layer.coords[:5] + rng.normal(size=(5, 2)) * 0.3,
                                    # corners on texel centres: edges through centres
                                    rng.integers(-4, res + 4, (30, 2)) + 0.5])
            extra[3] = np.nan
            coords = np.concatenate([layer.coords, extra])
            v = len(layer.coords)
            lattice = v + 25 + rng.integers(0, 30, (40, 3))
            faces = np.concatenate([faces, rng.integers(0, len(coords), (30, 3)),
                                    [[v, v, v + 1], [v + 3, v + 4, v + 5]],
                                    lattice]).astype(np.int64)
            extensions = np.concatenate([maps.extensions, np.column_stack(
                [np.zeros(15, np.int64), rng.integers(0, len(coords), (15, 2))]),
                np.column_stack([np.zeros(15, np.int64), v + 25 + rng.integers(0, 30, (15, 2))])])
        keep = 0.3 if case % 2 else 0.8
        drawn = np.sort(rng.permutation(len(faces))[: int(len(faces) * keep)])
        if case == 1:
            extensions = extensions[:3]  # the circle left mostly open: far holes
        want = np.full((res, res), -1, np.int32)
        fill_faces(want, coords, faces, drawn)
        fill_extensions(want, coords, extensions, len(faces), half, reach)
        table = mapfill._layer_triangles(coords, faces, drawn, extensions, len(faces), half,
                                         reach, res)
        assert len(table[0]) == len(drawn) + 2 * len(extensions)
        checked += _hole_fills(rng, want, table, len(drawn))
    assert checked > 400


def test_hole_fill_takes_a_tie_at_the_corner_of_a_triangle_s_texels():
    """A hole's nearest texels tie, the one the rule takes (the lesser column) at the
    corner of its triangle's texel range, exactly as far as the search's bound (the other,
    looked up): that triangle is tried all the same."""
    coords = np.array([[5.3, 5.3], [5.8, 5.4], [5.4, 5.8], [9.3, 1.3], [9.8, 1.4], [9.4, 1.8]])
    faces = np.array([[0, 1, 2], [3, 4, 5]], np.int64)
    want = np.full((16, 16), -1, np.int32)
    fill_faces(want, coords, faces, np.arange(2))
    assert np.argwhere(want >= 0).tolist() == [[1, 9], [5, 5]]
    table = mapfill._layer_triangles(coords, faces, np.arange(2), np.zeros((0, 3), np.int64),
                                     2, 8.0, 6.0, 16)
    ids = want.copy()
    texels = np.array([[1, 5], [1, 9]], np.int64)  # the hole (row 1, column 5), the tie
    assert mapfill._fill_holes(ids, texels, texels[:1], *table, 2)
    assert ids[1, 5] == 0 == want[5, 5]


def _one_texel_faces(texels, res):
    """A layer of faces each holding one texel (row, column) alone, in order: (the fill
    twins' whole layer, its _layer_triangles table)."""
    coords = np.array([[x + dx, y + dy] for y, x in texels
                       for dx, dy in ((0.2, 0.2), (0.8, 0.3), (0.3, 0.8))])
    faces = np.arange(len(coords), dtype=np.int64).reshape(-1, 3)
    drawn = np.arange(len(faces))
    want = np.full((res, res), -1, np.int32)
    fill_faces(want, coords, faces, drawn)
    assert np.argwhere(want >= 0).tolist() == sorted([list(t) for t in texels])
    return want, mapfill._layer_triangles(coords, faces, drawn, np.zeros((0, 3), np.int64),
                                          len(faces), res / 2.0, res / 3.0, res)


def test_hole_fill_keeps_a_tie_at_the_bound_of_its_ring_of_cells():
    """Two filled texels tie at squared distance 289 (17 = 15 + 2 texels straight down,
    and 8^2 + 15^2): the one the rule takes (the lesser column) is as far as the search's
    bound (the other, looked up) and lies in a ring of cells whose nearest texel is that
    far: the ring is searched all the same."""
    want, table = _one_texel_faces([(32, 20), (7, 35)], 64)
    assert nearest_filled_texel(want, 15, 20) == (32, 20)
    ids = want.copy()
    texels = np.array([[15, 20], [7, 35]], np.int64)
    assert mapfill._fill_holes(ids, texels, texels[:1], *table, 2)
    assert ids[15, 20] == 0 == want[32, 20]


def test_hole_fill_rings_start_at_the_hole_s_own_cell():
    """A hole 4 texels into its cell (the cells start 9 texels left of the other hole),
    its nearest filled texel 6 texels left, in the cell before its own, nearer than its
    bound (a looked-up texel 8 below): found in the first ring (a ring counted from the
    cell the hole would be in 4 texels on stops before it)."""
    want, table = _one_texel_faces([(30, 24), (38, 30)], 64)
    ids = want.copy()
    texels = np.array([[30, 27], [30, 30], [38, 30]], np.int64)
    assert mapfill._fill_holes(ids, texels, texels[:2], *table, 2)
    assert ids[30, 27] == ids[30, 30] == 0


def test_hole_fill_leaves_a_search_too_long_to_the_whole_layer():
    """Many holes far from the one filled texel (an open patch's lookups landing mostly
    outside it): past _HOLE_WORK units of work a texel of the map, _fill_holes answers
    False and writes nothing (the whole layer's build then takes over, tested with the
    maps built for their lookups); with few holes the same layer is answered."""
    res = 40
    coords = np.array([[20.2, 20.2], [20.8, 20.3], [20.3, 20.8]])
    faces = np.array([[0, 1, 2]], np.int64)
    want = np.full((res, res), -1, np.int32)
    fill_faces(want, coords, faces, np.arange(1))
    table = mapfill._layer_triangles(coords, faces, np.arange(1), np.zeros((0, 3), np.int64),
                                     1, 20.0, 15.0, res)
    holes = np.argwhere(want < 0).astype(np.int64)  # every empty texel looked up
    texels = np.concatenate([holes, [[20, 20]]])
    ids = want.copy()
    assert mapfill._HOLE_WORK * res * res < len(holes) * len(texels)
    assert not mapfill._fill_holes(ids, texels, holes, *table, 1)
    np.testing.assert_array_equal(ids, want)
    few = holes[::97]
    assert mapfill._fill_holes(ids, texels[::97], few, *table, 1)
    assert (ids[few[:, 0], few[:, 1]] == 0).all()


def test_hole_fill_of_random_small_layers_matches_the_fill_twins():
    """_fill_holes on many small random layers (1 to 64 texels a side; clustered, spread,
    off-map, NaN and huge corners; holes at the corners and edges, marks sparse to dense):
    as the fill twins' whole layer and the nearest rule wherever it answers, unwritten
    where it leaves the layer to the whole build."""
    rng = np.random.default_rng(31)
    answered = 0
    for _ in range(300):
        res = int(rng.choice([1, 2, 3, 7, 8, 9, 16, 17, 33, 64]))
        nv = int(rng.integers(3, 40))
        kind = int(rng.integers(0, 4))
        if kind == 0:  # lattice
            coords = rng.integers(-3, res + 3, (nv, 2)) + rng.choice([0.0, 0.5], (nv, 2))
        elif kind == 1:  # a cluster
            coords = rng.uniform(0, res, 2) + rng.normal(size=(nv, 2)) * rng.choice([0.3, 3.0])
        else:  # spread, some off the map
            coords = rng.uniform(-res, 2 * res, (nv, 2)) if kind == 2 else \
                rng.uniform(-2, res + 2, (nv, 2))
        if rng.random() < 0.2:
            coords[rng.integers(0, nv)] = np.nan
        if rng.random() < 0.1:
            coords[rng.integers(0, nv)] = rng.choice([1e15, -1e15])
        nf = int(rng.integers(0, 12))
        faces = rng.integers(0, nv, (nf, 3)).astype(np.int64)
        drawn = np.sort(rng.permutation(nf)[: int(rng.integers(0, nf + 1))]).astype(np.int64)
        ne = int(rng.integers(0, 5))
        extensions = np.column_stack([np.zeros(ne, np.int64), rng.integers(0, nv, (ne, 2))])
        half, reach = res / 2.0, float(rng.uniform(0.3, 0.8)) * res
        want = np.full((res, res), -1, np.int32)
        fill_faces(want, coords, faces, drawn)
        fill_extensions(want, coords, extensions, nf, half, reach)
        if not (want < 0).any():
            continue
        table = mapfill._layer_triangles(coords, faces, drawn, extensions, nf, half, reach,
                                         res)
        marks = rng.random((res, res)) < rng.choice([0.0, 0.02, 0.1, 0.5])
        ey, ex = np.nonzero(want < 0)
        j = int(rng.integers(0, len(ey)))
        marks[ey[j], ex[j]] = True
        if rng.random() < 0.3:
            marks[[0, 0, res - 1, res - 1], [0, res - 1, 0, res - 1]] = True
        ids = np.where(marks, want, rng.integers(-3, 40, (res, res))).astype(np.int32)
        stale = ids.copy()
        texels = np.argwhere(marks).astype(np.int64)
        holes = np.argwhere(marks & (want < 0)).astype(np.int64)
        if not mapfill._fill_holes(ids, texels[rng.permutation(len(texels))], holes, *table,
                                   len(drawn)):
            np.testing.assert_array_equal(ids, stale)
            continue
        expect = stale.copy()
        for y, x in holes:
            expect[y, x] = want[nearest_filled_texel(want, y, x)]
        np.testing.assert_array_equal(ids, expect)
        answered += len(holes)
    assert answered > 800


def test_hole_fill_of_lattice_triangles_matches_the_fill_twins():
    """_fill_holes on layers of lattice triangles and quads (every corner on a texel
    centre, so edges run through centres and a triangle's winding decides which texels it
    holds; many nearest texels tie on distance): as the fill twins and the nearest rule;
    and a layer that fills nothing gives no answer and writes nothing."""
    rng = np.random.default_rng(0)
    res, half, reach = 48, 24.0, 30.0
    checked = 0
    for case in range(40):
        coords = rng.integers(-4, res + 4, (60, 2)) + 0.5
        faces = rng.integers(0, len(coords), (80 if case else 0, 3)).astype(np.int64)
        drawn = np.arange(len(faces))
        extensions = np.column_stack([np.zeros(20 if case else 0, np.int64),
                                      rng.integers(0, len(coords), (20 if case else 0, 2))])
        want = np.full((res, res), -1, np.int32)
        fill_faces(want, coords, faces, drawn)
        fill_extensions(want, coords, extensions, len(faces), half, reach)
        table = mapfill._layer_triangles(coords, faces, drawn, extensions, len(faces), half,
                                         reach, res)
        checked += _hole_fills(rng, want, table, len(drawn), (0.01, 0.04))
    assert checked > 500


@pytest.mark.parametrize("res, layers", [(17, 2), (61, 3), (97, 8)])
def test_maps_built_together_give_each_part_s_maps_at_its_lookups(res, layers):
    """build_maps_together with the parts' lookups joined (each layer's texels listed from
    the points' cells: _lookup_texels, _texels_box) gives at every looked-up texel the
    ids and core of the part's maps built alone for the same lookups (whose texels are
    found from the marks): a torus split into parts, one part with no lookups, NaN,
    repeated and far points among the others."""
    from reflectcli.virtual.shape import reflector_shape

    rng = np.random.default_rng(res + layers)
    t = primitives.torus(1.0, 0.4, 20, 10)
    shape = reflector_shape(t.corners, t.normals, True)
    assert len(shape.parts) >= 3
    eye = np.array([0.7, 2.5, 4.0])
    setups, alone, lookups, starts = [], [], [], [0]
    for p, part in enumerate(shape.parts):
        n = 0 if p == 1 else int(rng.integers(20, 80))
        points = rng.normal(size=(n, 3)) * rng.uniform(0.5, 8.0)
        if n:
            points[2] = np.nan
            points[3] = points[4]
            points[5] = [1e30, 0.0, 0.0]
        center = part.mesh.vertices.mean(axis=0)
        near = 1.1 * np.linalg.norm(part.mesh.vertices - center, axis=1).max()
        args = (part.mesh, eye, center, near, max(30.0, near * 1.01), res, layers,
                part.boundary, points, None if p % 2 else rng.normal(size=3))
        setups.append(explosion.map_setup(*args))
        alone.append(explosion.build_explosion_maps(*args))
        lookups.append(points)
        starts.append(starts[-1] + n)
    joined = explosion.build_maps_together(
        setups, joined_lookups=(np.concatenate(lookups), np.array(starts, np.int64)))
    # in a workspace, twice: the same maps at the looked-up texels, its marks all False
    # after each call (given back zeroed: not cleared whole on the next)
    from reflectcli.raster.rasterize import RasterWorkspace

    ws = RasterWorkspace()
    for _ in range(2):
        again = explosion.build_maps_together(
            setups, joined_lookups=(np.concatenate(lookups), np.array(starts, np.int64)),
            ws=ws)
        marks = ws.get("maps_needed", joined.ids.shape, np.bool_)
        assert not marks.any() and ws._arrays["maps_needed:zeroed"]
        looked = [(k, cy, cx) for p in range(len(setups))
                  for cx, cy, lo in joined.cell[starts[p]:starts[p + 1]]
                  for k in (joined.layer_start[p] + lo, joined.layer_start[p] + lo + 1)]
        for k, cy, cx in looked:
            assert again.ids[k, cy, cx] == joined.ids[k, cy, cx]
            assert again.core[k, cy, cx] == joined.core[k, cy, cx]
    checked = 0
    for p, maps in enumerate(alone):
        k0 = joined.layer_start[p]
        for cx, cy, lo in joined.cell[starts[p]:starts[p + 1]]:
            for j in (lo, lo + 1):
                assert joined.ids[k0 + j, cy, cx] == maps.all_ids[j, cy, cx]
                assert joined.core[k0 + j, cy, cx] == maps.all_cores[j, cy, cx]
                checked += 1
    assert checked > 100


def _matmul_sums_as_the_kernel_does() -> bool:
    """Whether this machine's numpy `@` takes a row of an (N, 3) x (3, 3) product as
    fma(p2, m2, fma(p1, m1, p0 m0)) and an (N, 3) x (3,) product as fma(p2, m2, fma(p0, m0,
    p1 m1)) (OpenBLAS's kernels on this machine kind), the order virtual.screen's kernel
    reproduces (checked against exact fused multiply-adds, not the kernel); elsewhere it
    matches numpy to rounding only."""
    rng = np.random.default_rng(11)
    p, m = rng.normal(size=(64, 3)), rng.normal(size=(3, 3))
    f = fused_multiply_add
    rows = np.array([[f(a[2], b[2], f(a[1], b[1], a[0] * b[0])) for b in m] for a in p])
    vec = np.array([f(a[2], m[0, 2], f(a[0], m[0, 0], a[1] * m[0, 1])) for a in p])
    return bool((p @ m.T == rows).all() and (p @ m[0] == vec).all())


def test_screen_from_world_matches_twin_bit_for_bit(part_meshes):
    """Projections in a kernel (screen._screen_rows) give numpy's numbers bit for bit where
    numpy's `@` sums as the kernel does: the mask's parts and spheres through the mask's
    camera and cameras at the other eyes, points behind the eye and on its plane (w <= 0:
    the same infinities and NaN); single rows (which numpy takes by other routes)."""
    from conftest import open_scene

    from reflectcli.virtual.screen import screen_from_world as fast

    meshes, eyes = part_meshes
    bits = _matmul_sums_as_the_kernel_does()
    base = open_scene("mask", "virtual", ["camera.width=64", "camera.height=64"]).camera(0)
    cameras = [base] + [dataclasses.replace(base, eye=eye, width=320, height=200)
                        for eye in eyes[1:]]
    for camera in cameras:
        m = camera.clip_from_world()
        for mesh in meshes:
            points = mesh.vertices
            _same(fast(points, m, camera.width, camera.height),
                  screen_from_world(points, m, camera.width, camera.height), bits)
        eye = camera.eye
        behind = np.array([eye, eye + 0.5 * (eye - camera.target), eye + camera.up,
                           camera.target])
        got = fast(behind, m, camera.width, camera.height)
        want = screen_from_world(behind, m, camera.width, camera.height)
        assert np.array_equal(np.isnan(got), np.isnan(want))
        _same(np.nan_to_num(got), np.nan_to_num(want), bits)
    for one in meshes[0].vertices[:40, None]:  # a single row: numpy's other routes
        _same(fast(one, m, 64, 64), screen_from_world(one, m, 64, 64), bits)
    assert fast(np.empty((0, 3)), m, 64, 64).shape == (0, 3)


def test_part_extent_matches_twin_bit_for_bit(part_meshes):
    """A part's bounds and front vertices in a kernel (part._extent) are numpy's bit for
    bit where its einsum sums as the kernel does, from every eye, about the ray focus and
    about points away from it."""
    from reflectcli.virtual.part import _extent

    meshes, eyes = part_meshes
    bits = _einsum_sums_as_the_kernels_do()
    rng = np.random.default_rng(5)
    scene_points = rng.normal(0.0, 4.0, (9, 3))
    for mesh in meshes:
        for eye in eyes:
            for centre in (explosion.ray_focus(mesh, eye), rng.normal(0.0, 1.0, 3)):
                front = np.empty(len(mesh.vertices), np.bool_)
                bound, far = _extent(mesh.vertices, mesh.normals, centre, scene_points, eye,
                                     front)
                want = part_extent(mesh.vertices, mesh.normals, centre, scene_points, eye)
                _same(np.array([bound, far]), np.array(want[:2]), bits)
                if bits:
                    assert np.array_equal(front, want[2])
    # vertices seen edge-on (n . (eye - v) exactly 0) face the eye, as numpy's >= has it
    vertices = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]])
    normals = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    front = np.empty(3, np.bool_)
    _extent(vertices, normals, np.zeros(3), scene_points, np.zeros(3), front)
    assert front.tolist() == [True, True, True]
    assert np.array_equal(front, part_extent(vertices, normals, np.zeros(3), scene_points,
                                             np.zeros(3))[2])


def test_lookup_texels_are_the_marked_texels_and_their_boxes():
    """_lookup_texels (each layer's texels from the points' cells) lists the texels
    _mark_parts marks from those cells (a point's texel in its part's layers lo and lo + 1),
    once per point marking it, in the points' order; _texels_box of a layer's list is
    _marked_box of its marks, empty (y0 > y1) for a layer no point marks."""
    rng = np.random.default_rng(21)
    res = 40
    layers = np.array([3, 2, 4, 3])
    layer_start = np.concatenate([[0], np.cumsum(layers)]).astype(np.int64)
    counts = np.array([7, 0, 1, 30])
    point_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    cell = np.zeros((counts.sum(), 3), np.int64)
    for p in range(len(counts)):
        rows = slice(point_start[p], point_start[p + 1])
        cell[rows, :2] = rng.integers(0, res, (counts[p], 2))
        cell[rows, 2] = rng.integers(0, layers[p] - 1, counts[p])
    cell[-3:] = cell[-4]  # points sharing a texel
    needed = np.zeros((layer_start[-1], res, res), bool)
    for p in range(len(counts)):
        for cx, cy, lo in cell[point_start[p]:point_start[p + 1]]:
            needed[layer_start[p] + lo:layer_start[p] + lo + 2, cy, cx] = True
    texel_start = np.full(layer_start[-1] + 1, 5, np.int64)  # overwritten
    texels = np.full((2 * len(cell), 2), -1, np.int64)
    explosion._lookup_texels(cell, point_start, layer_start, texel_start, texels)
    empty = 0
    assert texel_start[0] == 0 and texel_start[-1] == len(texels) and (texels >= 0).all()
    for k in range(layer_start[-1]):
        listed = texels[texel_start[k]:texel_start[k + 1]]
        want = mapfill._marked_box(needed[k])
        box = explosion._texels_box(listed)
        if want[0] > want[1]:
            assert box[0] > box[1]
            empty += 1
        else:
            assert box == want
        p = np.searchsorted(layer_start, k, side="right") - 1
        mine = [(cy, cx) for cx, cy, lo in cell[point_start[p]:point_start[p + 1]]
                if layer_start[p] + lo in (k, k - 1)]
        assert [tuple(t) for t in listed] == mine
        marked = mapfill._marked_texels(needed[k], 0, res - 1, 0, res - 1)
        assert {tuple(t) for t in listed} == {tuple(t) for t in marked}
    assert empty >= 2  # part 1's layers, at least
    # the lists clear every mark (build_maps_together gives its workspace's marks back so)
    explosion._unmark(needed, texel_start, texels)
    assert not needed.any()


def test_ray_foci_are_each_mesh_s_ray_focus(part_meshes):
    """ray_foci (the parts' solves in one numpy call) gives each mesh ray_focus's bits:
    the mask's parts and spheres from every eye, with meshes whose normal equations are
    ill-posed (no front vertex: the vertex mean) among them."""
    meshes, eyes = part_meshes
    sphere = meshes[0]
    away = sphere.vertices - eyes[0]
    away /= np.linalg.norm(away, axis=1, keepdims=True)
    turned = dataclasses.replace(sphere, normals=away)  # no front vertex from eyes[0]
    for eye in eyes:
        group = [turned] + meshes + [turned]
        for got, mesh in zip(explosion.ray_foci(group, eye), group, strict=True):
            assert got.tobytes() == explosion.ray_focus(mesh, eye).tobytes()
            a, b, front = explosion._focus_sums(mesh.vertices, mesh.normals, eye)
            if front < 3 or np.linalg.cond(a) > 1e8:
                assert got.tobytes() == mesh.vertices.mean(axis=0).tobytes()
            else:
                assert got.tobytes() == np.linalg.solve(a, b).tobytes()


@pytest.mark.parametrize("layers", [1, 2, 6])
def test_layer_radii_of_several_parts_are_each_part_s(layers):
    """layer_radii of P parts' near and far radii in one call (parts.py) gives each part
    the bits of its own call, and both those of np.geomspace from near to far."""
    rng = np.random.default_rng(layers)
    near = rng.uniform(1e-6, 10.0, 40) * 10.0 ** rng.integers(-3, 4, 40)
    far = near * rng.uniform(1.0000001, 1e4, 40)
    for equal in (False, True):
        if equal:  # a part with near == far: numpy's linspace takes another branch
            far[7] = near[7]
        together = explosion.layer_radii(near, far, layers)
        assert together.shape == (40, max(layers, 2))
        if not equal:  # numpy's own call for all parts, bit for bit
            whole = np.geomspace(near, far, max(layers, 2), axis=-1)
            assert together.tobytes() == whole.tobytes()
        for p in range(40):
            alone = explosion.layer_radii(near[p], far[p], layers)
            assert together[p].tobytes() == alone.tobytes()
            assert alone.tobytes() == np.geomspace(near[p], far[p], max(layers, 2)).tobytes()
            assert alone[0] == near[p] and alone[-1] == far[p]


def test_surely_well_posed_never_contradicts_numpy():
    """_surely_well_posed (ray_foci's closed-form test) says sure only of matrices whose
    np.linalg.cond is not above 1e8, and is sure of the well-conditioned ones: random
    positive semi-definite 3x3 matrices with condition numbers from 1 to 1e14 (around 1e7
    and 1e8 densely), double and triple eigenvalues, scales from 1e-12 to 1e12, the zero
    matrix, matrices with NaN or inf, and ones so small or large that squares underflow or
    overflow."""
    rng = np.random.default_rng(21)
    mats = []
    for _ in range(20000):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        top = 10.0 ** rng.uniform(-12, 12)
        cond = 10.0 ** rng.choice([rng.uniform(0, 14), rng.uniform(6.5, 8.5)])
        e = np.sort(top / 10.0 ** rng.uniform(0, np.log10(cond), 3))
        e[-1], e[0] = top, top / cond
        kind = rng.integers(4)
        if kind == 1:
            e[1] = e[0]  # a double least eigenvalue
        elif kind == 2:
            e[1] = e[2]  # a double largest
        elif kind == 3 and rng.random() < 0.2:
            e[:] = top  # q times the identity
        m = (q * e) @ q.T
        mats.append((m + m.T) / 2.0)  # exactly symmetric, as the sums are
    mats += [np.zeros((3, 3)), np.full((3, 3), np.nan), np.diag([1.0, np.inf, 1.0]),
             np.diag([1.0, 1.0, 0.0]), np.diag([1.0, 1.0, 1e-8]), np.diag([1.0, 1.0, 1e-9]),
             np.diag([1e-300, 1e-300, 1e-310]), np.diag([1e-160, 1e-160, 1e-170]),
             np.diag([1e300, 1e300, 1e290]), np.full((3, 3), 1e-200) + np.eye(3) * 1e-190]
    a = np.array(mats)
    sure = np.empty(len(a), np.bool_)
    explosion._surely_well_posed(a, sure)
    with np.errstate(all="ignore"):
        cond = np.array([np.linalg.cond(m) if np.isfinite(m).all() else np.nan for m in a])
    assert not (sure & ~(cond <= 1e8)).any()  # never sure where numpy says above (or NaN)
    assert (cond[sure] < 1e7).all()  # what it claims: below 1e7 beyond doubt
    scale = np.trace(a, axis1=1, axis2=2) / 3.0
    # sure of every well-conditioned one not so small that its squares could underflow
    assert sure[(cond < 1e5) & (scale > 1e-150)].all()
    assert not sure[scale <= 1e-150].any()
    assert sure.sum() > len(a) // 5 and (~sure).sum() > len(a) // 4
