"""Virtual-vertex searches (exact sphere / cylinder / profile methods, spheres together)
and the virtual passes' kernels (mirror boxes, gathering, crack fill, views, stencils,
labels, composition) against their slow twins."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import compiled_only
from naive import (
    faces_behind,
    mirror_on_circle,
    profile_one,
)
from naive import fill_cracks as naive_fill_cracks
from naive import gather_corners as naive_gather_corners
from naive import mirror_boxes as naive_mirror_boxes
from naive import mirror_rays as naive_mirror_rays
from naive import part_stencil as naive_part_stencil
from naive import part_views as naive_part_views

from reflectcli.camera import Camera
from reflectcli.raster.rasterize import FLAG_MIRROR, FLAG_SKIP
from reflectcli.scene import primitives
from reflectcli.virtual import circle, compose, direct, refine


def circle_cases(rng, n=600):
    """Points around a unit sphere at the origin seen from an eye at distance ~4: visible,
    hidden behind it, inside it, on the line through the center and the eye (both sides),
    just off that line behind the sphere (a bracket of nearly pi), grazing its silhouette;
    more than two of circle.BLOCK, so blocks full and partial are both met."""
    eye = np.array([0.5, 0.8, 4.0])
    pts = list(rng.normal(size=(n, 3)) * 2.5)
    pts += [eye * 0.5, -eye, 2.0 * eye, np.array([0.1, 0.2, -0.3]), np.array([0.0, 0.0, -3.0])]
    side = np.cross(eye, [0.0, 1.0, 0.0])
    side /= np.linalg.norm(side)
    pts += [-2.0 * eye + 1e-9 * side, -2.0 * eye + 1e-5 * side]
    along = eye / np.linalg.norm(eye)
    pts += [1.0001 * side + t * along for t in (-2.0, -0.5, 0.0, 0.3)]
    return eye, np.array(pts)


def test_sphere_blocks_do_not_change_answers():
    """A point's virtual vertex is the same bytes whichever block (and lane) it is in."""
    eye, pts = circle_cases(np.random.default_rng(5))
    got, hidden = circle.sphere_virtual_vertices(pts, eye, np.zeros(3), 1.0)
    for i in range(0, len(pts), 7):
        one, one_h = circle.sphere_virtual_vertices(pts[i:i + 1], eye, np.zeros(3), 1.0)
        assert one.tobytes() == got[i:i + 1].tobytes() and one_h[0] == hidden[i]
    shifted, _ = circle.sphere_virtual_vertices(pts[3:], eye, np.zeros(3), 1.0)
    assert shifted.tobytes() == got[3:].tobytes()


@pytest.mark.parametrize("seed", range(2))
def test_sphere_virtual_vertices_match_twin(seed):
    eye, pts = circle_cases(np.random.default_rng(seed))
    center, radius = np.array([0.0, 0.0, 0.0]), 1.0
    got, hidden = circle.sphere_virtual_vertices(pts, eye, center, radius)
    for p, g, h in zip(pts, got, hidden, strict=True):
        want, want_h = mirror_on_circle(eye, p, center, radius)
        assert h == want_h, p
        np.testing.assert_allclose(g, want, atol=1e-6 * (1 + np.linalg.norm(p)))
    assert hidden.any() and not hidden.all()


@pytest.mark.parametrize("seed", range(2))
def test_cylinder_virtual_vertices_match_twin(seed):
    rng = np.random.default_rng(seed)
    eye, pts = circle_cases(rng)
    origin, axis = np.array([0.1, -1.0, 0.0]), np.array([0.2, 1.0, 0.1])
    got, hidden = circle.cylinder_virtual_vertices(pts, eye, origin, axis, 0.7)
    a = axis / np.linalg.norm(axis)
    for p, g, h in zip(pts, got, hidden, strict=True):
        want, want_h = mirror_on_circle(eye, p, origin, 0.7, a)
        assert h == want_h, p
        np.testing.assert_allclose(g, want, atol=1e-6 * (1 + np.linalg.norm(p)))
    assert hidden.any()


@pytest.mark.parametrize("seed", range(2))
def test_profile_virtual_vertices_match_twin(seed):
    rng = np.random.default_rng(seed)
    # a convex arc bulging toward +z (the viewer), normals roughly radial, not exactly
    ang = np.linspace(-1.0, 1.0, 9)
    profile = np.stack([np.sin(ang), np.cos(ang) - 1.0], 1)
    normals = np.stack([np.sin(ang * 1.05), np.cos(ang * 1.05)], 1)
    frame = np.eye(4)
    frame[:3, 3] = (0.2, -0.5, 0.1)
    eye = np.array([0.3, 1.0, 3.0])
    pts = np.concatenate([rng.normal(size=(120, 3)) * 2.0 + [0, 0, 1.5],
                          [[0.2, 0.0, -2.0], [3.0, 0.0, 0.5], [-0.1, 0.3, 0.4]]])
    got, hidden = direct.profile_virtual_vertices(pts, eye, profile, normals, frame)
    inv = np.linalg.inv(frame)
    e = inv[:3, :3] @ eye + inv[:3, 3]
    for p, g, h in zip(pts, got, hidden, strict=True):
        local = inv[:3, :3] @ p + inv[:3, 3]
        want, want_h = profile_one(local, e, profile, normals)
        assert h == want_h, p
        np.testing.assert_allclose(g, frame[:3, :3] @ want + frame[:3, 3], atol=1e-9)
    assert hidden.any() and not hidden.all()


def test_mirror_boxes_match_twin():
    rng = np.random.default_rng(3)
    surface = rng.integers(-1, 4, (23, 31)).astype(np.int32)
    surface[surface == 5] = 0
    surface[:, :] = np.where(surface == 4, 1, surface)  # mirror 2 (surface 4) absent
    got = compose.mirror_boxes(surface, 2, 3)
    want = naive_mirror_boxes(surface, 2, 3)
    for g, x in zip(got, want, strict=True):
        np.testing.assert_array_equal(g, x)
    assert got[0][2] == 0 and got[0][0] > 0


def test_gather_corners_match_twin():
    rng = np.random.default_rng(4)
    virtual = rng.normal(size=(40, 3)) * 5
    hidden = rng.random(40) < 0.6
    corner_index = rng.integers(0, 40, (70, 3))
    surface = rng.integers(0, 6, 70)
    corners = np.empty((70, 3, 3), np.float32)
    flags = np.empty(70, np.uint8)
    compose.gather_corners(virtual, hidden, corner_index, surface, 4, corners, flags)
    want_corners, want_flags = naive_gather_corners(virtual, hidden, corner_index, surface, 4)
    assert corners.tobytes() == want_corners.tobytes()
    np.testing.assert_array_equal(flags, want_flags)
    assert (flags & FLAG_SKIP).any() and (flags & FLAG_MIRROR).any()


@pytest.mark.parametrize("seed", range(3))
def test_fill_cracks_match_twin(seed):
    rng = np.random.default_rng(seed)
    h, w = 19, 23
    covered = rng.random((h, w)) < 0.8
    stencil = covered | (rng.random((h, w)) < 0.7)
    stencil[:2] = False  # a box that is not the whole image
    # the pass's triangle ids: drawn only on the stencil; elsewhere whatever an earlier
    # pass left (ids or -1), which must not count
    triangle = np.where(covered, rng.integers(0, 50, (h, w)), -1).astype(np.int32)
    stale = ~stencil & (rng.random((h, w)) < 0.5)
    triangle[stale] = rng.integers(0, 50, int(stale.sum()))
    covered &= stencil
    colors = rng.random((h, w, 3)).astype(np.float32)
    want = colors.copy()
    naive_fill_cracks(want, covered, stencil)
    ys, xs = np.nonzero(stencil)
    compose.fill_cracks(colors, triangle, stencil, ys.min(), ys.max() + 1, xs.min(),
                        xs.max() + 1)
    assert colors.tobytes() == want.tobytes()


@compiled_only
def test_mirror_rays_match_reflector_grid():
    """R at mirror pixels from barycentrics recovered in the kernel: the very bytes of
    reflector_grid from the buffers' own b1, b2; NaN at the box's other pixels."""
    from reflectcli.raster.rasterize import rasterize as fast_rasterize

    cam = Camera(np.array([0.0, 0.4, 3.0]), np.zeros(3), np.array([0.0, 1.0, 0.0]), 50.0, 40,
                 30, 0.1, 100.0)
    sphere = primitives.uv_sphere(1.0, 12)
    corners = sphere.corners.astype(np.float32)
    normals = sphere.normals.astype(np.float32)
    m = cam.clip_from_world()
    buffers = fast_rasterize(corners, np.zeros(len(corners), np.uint8), m, 40, 30)
    mirror = np.zeros((30, 40), bool)
    mirror[:, 12:] = True  # a part of the sphere only
    tri = buffers.triangle
    masked = np.where(mirror, tri, -1).astype(np.int32)
    _, want = refine.reflector_grid(masked, buffers.b1, buffers.b2, corners, normals, cam.eye)
    r = np.full((30, 40, 3), 7.0)
    refine.mirror_rays(tri, mirror, corners, m, corners, normals, np.asarray(cam.eye, float),
                       3, 27, 5, 38, r)
    box = (slice(3, 27), slice(5, 38))
    assert r[box].tobytes() == want[box].tobytes()
    assert (r[:3] == 7.0).all() and (r[:, 38:] == 7.0).all()
    assert np.isfinite(r[box]).sum() > 300
    # and the slow twin, barycentrics worked in float64 from the pixel centers
    slow = naive_mirror_rays(tri, mirror, corners, m, corners, normals, np.asarray(cam.eye),
                             (3, 27, 5, 38))
    assert np.array_equal(np.isnan(r[box]), np.isnan(slow[box]))
    np.testing.assert_allclose(r[box], slow[box], atol=2e-5)  # float32 barycentrics


def test_reflector_rays_match_reflector_grid():
    """Q and R over the rows' spans from barycentrics recovered in the kernel: the very
    bytes of reflector_grid from the buffers' own b1, b2 (held to its slow twin); NaN at a
    span's pixels with no triangle; the pixels outside the spans left as they were."""
    from reflectcli.raster.rasterize import rasterize as fast_rasterize

    cam = Camera(np.array([0.0, 0.4, 3.0]), np.zeros(3), np.array([0.0, 1.0, 0.0]), 50.0, 40,
                 30, 0.1, 100.0)
    sphere = primitives.uv_sphere(1.0, 12)
    corners = sphere.corners.astype(np.float32)
    normals = sphere.normals.astype(np.float32)
    buffers = fast_rasterize(corners, np.zeros(len(corners), np.uint8),
                             cam.clip_from_world(), 40, 30)
    tri = buffers.triangle
    want_q, want_r = refine.reflector_grid(tri, buffers.b1, buffers.b2, corners, normals,
                                           cam.eye)
    spans = np.zeros((30, 2), np.int64)
    for y in range(30):
        cols = np.flatnonzero(tri[y] >= 0)
        if cols.size:
            spans[y] = cols[0], cols[-1] + 1
    spans[12] = 3, 37  # wider than its pixels: the empty ones get NaN
    q, r = np.full((30, 40, 3), 7.0), np.full((30, 40, 3), 7.0)
    got = refine.reflector_rays(buffers, corners, normals, cam.eye, spans, out=(q, r))
    assert got[0] is q and got[1] is r
    inside = np.zeros((30, 40), bool)
    for y, (x0, x1) in enumerate(spans):
        inside[y, x0:x1] = True
    assert inside.sum() > 300 and (tri[12, 3:37] < 0).any()
    assert q[inside].tobytes() == want_q[inside].tobytes()
    assert r[inside].tobytes() == want_r[inside].tobytes()
    assert (q[~inside] == 7.0).all() and (r[~inside] == 7.0).all()


def test_part_stencil_matches_twin():
    rng = np.random.default_rng(11)
    triangle = rng.integers(-1, 60, (21, 27)).astype(np.int32)
    surface = rng.integers(-1, 5, (21, 27)).astype(np.int32)
    faces = np.array([0, 3, 4, 9, 29])  # of the reflector's 30 faces, triangles 20 .. 49
    in_part = np.zeros(31, bool)
    in_part[faces] = True
    out = np.empty((21, 27), np.bool_)
    compose.part_stencil(triangle, surface, 3, 20, in_part, out)
    want = naive_part_stencil(triangle, surface, 3, 20, faces, 30)
    np.testing.assert_array_equal(out, want)
    assert want.sum() > 5


def test_faces_behind_match_twin():
    """PartView.faces_behind (the hidden map's faces of points behind the reflector alone)
    against its twin: points on and off the image, on its edges, behind the eye, deeper and
    shallower than the depth, NaN and infinite."""
    from reflectcli.virtual.view import PartView, PointsOnScreen

    rng = np.random.default_rng(4)
    h, w, count = 23, 31, 12
    triangle = rng.integers(-1, count, (h, w)).astype(np.int32)
    local = np.full(count + 1, -1, np.int32)
    local[[1, 4, 5, 9]] = np.arange(4)
    depth = rng.uniform(1.0, 3.0, (h, w))
    depth[0, :5] = np.inf  # no reflector there
    n = 400
    screen = np.column_stack([rng.uniform(-3, w + 3, n), rng.uniform(-3, h + 3, n),
                              rng.uniform(-1.0, 4.0, n)])
    screen[:40, :2] = np.floor(screen[:40, :2])  # on pixel edges
    edges = [[0.0, 0.0, 5.0], [w, 3.0, 5.0], [w - 1e-9, 3.0, 5.0], [3.0, h, 5.0],
             [-1e-12, 2.0, 5.0], [np.nan, 2.0, 5.0], [2.0, np.inf, 5.0], [2.0, 2.0, np.nan],
             [2.0, 2.0, np.inf], [2.0, 2.0, 0.0], [-np.inf, 1.0, 5.0], [1.0, 1.0, -2.0]]
    screen = np.concatenate([screen, edges])
    view = PartView(np.zeros((h, w), np.int16), 0, triangle, local, None, PointsOnScreen())
    got = view.faces_behind(screen, depth)
    np.testing.assert_array_equal(got, faces_behind(screen, depth, triangle, local))
    assert (got >= 0).sum() > 20 and (got < 0).sum() > 20


def test_part_views_match_twin():
    """view.part_views (one pass, every part, one owner plane) against its twin part by
    part: each part's face under each pixel (the paper's hidden map: local[triangle]), its
    pixels, and its tiles as np.unique of the pixels' tile ids."""
    from reflectcli.virtual.view import PartView, PointsOnScreen, part_views

    rng = np.random.default_rng(12)
    h, w, count, size = 37, 50, 40, 12
    triangle = rng.integers(-1, count, (h, w)).astype(np.int32)
    triangle[:, :20] = -1  # tiles with no pixel of any part
    faces = [np.array([0, 5, 7]), np.arange(10, 30), np.array([39])]
    local = np.full((len(faces), count + 1), -1, np.int32)
    part_of = np.full(count + 1, -1, np.int16)
    for p, f in enumerate(faces):
        local[p, f] = np.arange(len(f))
        part_of[f] = p
    triangle[5] = -1  # a row with no pixel of any part
    triangle[6, 30:] = -1
    triangle[7, 0] = 10  # a span from column 0
    owner = np.empty((h, w), np.int16)
    marks = np.zeros((len(faces), h // size + 1, w // size + 1), np.bool_)
    spans = np.full((h, 2), -7, np.int64)
    part_views(triangle, part_of, size, owner, marks, spans)
    ys, xs = np.indices((h, w))
    for y in range(h):  # each row's span: its first part pixel to past its last
        cols = np.flatnonzero(part_of[triangle[y]] >= 0)
        want_span = (cols[0], cols[-1] + 1) if cols.size else (0, 0)
        assert tuple(spans[y]) == want_span
    assert tuple(spans[5]) == (0, 0) and spans[6, 1] <= 30 and spans[7, 0] == 0
    for p, (want, want_inside, want_tiles) in enumerate(naive_part_views(triangle, local,
                                                                          size)):
        view = PartView(owner, p, triangle, local[p], None, PointsOnScreen())
        np.testing.assert_array_equal(view.local[view.triangle[ys, xs]], want)
        np.testing.assert_array_equal(owner == p, want_inside)
        np.testing.assert_array_equal(np.flatnonzero(marks[p]), want_tiles)


def test_pass_labels_match_twin():
    from naive import pass_labels as naive_pass_labels

    rng = np.random.default_rng(8)
    h, w = 21, 17
    surface = rng.integers(-1, 9, (h, w)).astype(np.int32)  # objects 0..3, mirrors 4..8
    depth = rng.uniform(0.5, 9.0, (h, w)).astype(np.float32)
    label_of = np.array([2, 0, 1, 3, 0], np.uint8)  # mirror 1 and 4 not drawn together
    labels = np.full((h, w), 99, np.uint8)
    stencil = np.zeros((h, w), np.bool_)
    floor = np.full((h, w), -1.0, np.float32)
    compose.pass_labels(surface, depth, 4, label_of, 2, h - 3, 1, w - 2, labels, stencil,
                        floor)
    want = naive_pass_labels(surface, depth, 4, label_of)
    box = (slice(2, h - 3), slice(1, w - 2))
    for got, expect in zip((labels, stencil, floor), want, strict=True):
        assert got[box].tobytes() == expect[box].tobytes()
    assert labels[0, 0] == 99 and floor[-1, -1] == -1.0  # outside the box: untouched
    assert set(np.unique(labels[box])) == {0, 1, 2, 3}


@pytest.mark.parametrize("seed", range(3))
def test_compose_passes_match_twin(seed):
    """Cracks filled within each label only (a neighbour of another label never counts as
    covered), then each label's reflectance added: the twins one label at a time."""
    from naive import compose_passes as naive_compose_passes

    rng = np.random.default_rng(seed)
    h, w = 19, 23
    labels = rng.integers(0, 4, (h, w)).astype(np.uint8)
    labels[:2] = 0
    labels[5:9, 4:12] = 2  # wide runs of one label: cracks to fill
    triangle = np.where(rng.random((h, w)) < 0.7, rng.integers(0, 50, (h, w)), -1)
    triangle = triangle.astype(np.int32)
    colors = rng.random((h, w, 3)).astype(np.float32)
    rgb = rng.random((h, w, 3)).astype(np.float32)
    reflectance = rng.random((3, 3)).astype(np.float32)
    labels[:, -2:] = 0  # and a box short of the image's right edge
    want_colors = colors.copy()
    want = naive_compose_passes(rgb, want_colors, triangle, labels, reflectance)
    got = rgb.copy()
    ys, xs = np.nonzero(labels)
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    # outside the box the buffers hold another frame's or pass's labels and triangles:
    # never read (a crack on the box's edge must not be filled from them)
    outside = np.ones((h, w), bool)
    outside[y0:y1, x0:x1] = False
    labels[outside] = rng.integers(1, 4, outside.sum())
    triangle[outside] = rng.integers(0, 50, outside.sum())
    compose.compose_passes(got, colors, triangle, labels, reflectance, y0, y1, x0, x1)
    assert colors.tobytes() == want_colors.tobytes()
    assert got.tobytes() == want.tobytes()
    assert not np.array_equal(got, rgb)


def test_spheres_together_give_each_sphere_s_bytes():
    """Several spheres' points in one call (spheres_virtual_vertices): each point the very
    bytes of its sphere's call alone, with empty spheres and spheres shorter than a block."""
    eye, pts = circle_cases(np.random.default_rng(6))
    rng = np.random.default_rng(7)
    more = rng.normal(size=(3 * circle.BLOCK + 11, 3)) * 3.0
    centers = np.array([[0.0, 0.0, 0.0], [0.5, -0.2, 0.1], [9.0, 9.0, 9.0], [-0.3, 0.2, 0.4]])
    radii = np.array([1.0, 0.7, 0.5, 1.2])
    parts = [pts, more[:circle.BLOCK + 5], np.zeros((0, 3)), more[circle.BLOCK + 5:]]
    points = np.ascontiguousarray(np.concatenate(parts))
    starts = np.cumsum([0] + [len(p) for p in parts])
    out = np.empty_like(points)
    hidden = np.empty(len(points), np.bool_)
    circle.spheres_virtual_vertices(points, eye, centers, radii, starts, out, hidden,
                                    circle.block_scratch())
    for s, part in enumerate(parts):
        want, want_hidden = circle.sphere_virtual_vertices(part, eye, centers[s], radii[s])
        assert out[starts[s]:starts[s + 1]].tobytes() == want.tobytes()
        assert hidden[starts[s]:starts[s + 1]].tobytes() == want_hidden.tobytes()


def test_part_labels_match_twin():
    """A reflector's part labels, stencil, depth floor and per-label boxes in its box, on
    random buffers (faces of other surfaces, ids outside the reflector's faces, labels
    with no pixel), against the twin; nothing outside the box is written."""
    from naive import part_labels as naive_part_labels

    from reflectcli.virtual.partpasses import part_labels

    rng = np.random.default_rng(12)
    h, w, first, count = 40, 56, 30, 50
    triangle = rng.integers(-1, first + count + 20, (h, w)).astype(np.int32)
    surface = rng.integers(0, 4, (h, w)).astype(np.int32)
    surface[5:30, 8:40] = 2  # the reflector's pixels lie in its box
    surface[:5] = np.where(surface[:5] == 2, 3, surface[:5])
    surface[30:] = np.where(surface[30:] == 2, 3, surface[30:])
    surface[:, :8] = np.where(surface[:, :8] == 2, 3, surface[:, :8])
    surface[:, 40:] = np.where(surface[:, 40:] == 2, 3, surface[:, 40:])
    depth = rng.uniform(1, 9, (h, w)).astype(np.float32)
    label_of = np.zeros(count + 1, np.uint8)
    label_of[:count] = rng.integers(1, 6, count)
    label_of[label_of == 4] = 3  # label 4 has no face: its box stays zero
    want = naive_part_labels(triangle, surface, 2, first, label_of, depth)
    labels = np.full((h, w), 77, np.uint8)
    stencil = np.ones((h, w), np.bool_)
    floor = np.full((h, w), -1.0, np.float32)
    boxes = np.empty((int(label_of.max()), 4), np.int64)
    part_labels(triangle, surface, 2, first, label_of, 5, 30, 8, 40, depth, labels, stencil,
                floor, boxes)
    np.testing.assert_array_equal(boxes, want[3])
    assert not boxes[3].any()
    for got, wanted, outside in zip((labels, stencil, floor), want[:3], (77, True, -1.0),
                                    strict=True):
        np.testing.assert_array_equal(got[5:30, 8:40], wanted[5:30, 8:40])
        inside = np.zeros((h, w), bool)
        inside[5:30, 8:40] = True
        assert (got[~inside] == outside).all()
    # a box of fewer rows than part_labels' bands (some bands hold none)
    few = np.where((np.arange(h) >= 10)[:, None] & (np.arange(h) < 13)[:, None], surface, 3)
    want = naive_part_labels(triangle, few, 2, first, label_of, depth)
    part_labels(triangle, few, 2, first, label_of, 10, 13, 8, 40, depth, labels, stencil,
                floor, boxes)
    np.testing.assert_array_equal(boxes, want[3])
    np.testing.assert_array_equal(labels[10:13, 8:40], want[0][10:13, 8:40])


def _mask_frame(threads):
    """The mask scene at 160 x 160 (several parts seen), prepared at `threads`."""
    import numba
    from conftest import SCENES

    from reflectcli.camera import camera_from_config
    from reflectcli.loading import load_config
    from reflectcli.scene.build import build_scene
    from reflectcli.techniques.virtual.technique import Virtual

    numba.set_num_threads(threads)
    path = str(SCENES / "mask.toml")
    cfg, _ = load_config(path, ["camera.width=160", "camera.height=160"], "virtual")
    scene = build_scene(cfg, path)
    cam = camera_from_config(cfg.camera, 0)
    technique = Virtual(cfg.technique)
    return cfg, scene, cam, technique, technique.prepare(scene)


@compiled_only
def test_view_rays_outside_the_spans_are_never_read(monkeypatch):
    """reflector_rays leaves the pixels outside the reflector's spans unwritten: whatever
    they hold, the mask's frame is the same bytes (the tile bounds, scans, seeds and
    refinement read a pixel only where a part owns it). The fills are plausible numbers, not
    NaN: the walks reject a NaN sample, which would hide a stray read (the last pixel of
    each span left at the fill changes the frame)."""
    import numba

    from reflectcli.frame import Frame
    from reflectcli.virtual import view

    cfg, scene, cam, technique, state = _mask_frame(numba.get_num_threads())
    real = view.reflector_rays
    frames = []
    for fill in (0.3, 0.7):
        def rays(alone, corners, normals, eye, spans, out=None, fill=fill):
            h, w = alone.triangle.shape
            return real(alone, corners, normals, eye, spans,
                        out=(np.full((h, w, 3), fill), np.full((h, w, 3), fill)))
        monkeypatch.setattr(view, "reflector_rays", rays)
        technique.forget_view(state)
        frame = technique.render(state, 0, cam)
        assert isinstance(frame, Frame)
        frames.append(frame.rgb.tobytes())
    assert frames[0] == frames[1]


@compiled_only
@pytest.mark.parametrize("threads", [1, 2])
def test_parts_together_give_each_part_s_answers(threads):
    """A reflector's parts worked stage by stage (parts_vertices: tile scans, maps,
    lookups and refinement each in one region for all parts; its arrays fresh or in a
    workspace used twice) give each part the very bytes of its own call
    (ExplosionPart.__call__, whose stages are held to their twins)."""
    import numba

    from reflectcli.raster.primary import render_primary
    from reflectcli.raster.rasterize import RasterWorkspace
    from reflectcli.virtual.compose import mirror_boxes
    from reflectcli.virtual.dispatch import explosion_group, reflector_parts
    from reflectcli.virtual.parts import _locals, parts_vertices

    before = numba.get_num_threads()
    try:
        cfg, scene, cam, technique, state = _mask_frame(threads)
        primary = render_primary(scene, 0, cam)
        tess = state.reflected.get(scene.geometry(0), scene.n_objects, 0,
                                   cfg.technique.tessellation, exact=False, weld=True)
        parts = [fn for _, fn in reflector_parts(cfg.technique, scene, primary, 0, cam,
                                                 state.scene_points, state.shapes,
                                                 state.views)]
        assert len(parts) > 4
        want = [part(tess.points, tess.corner_index) for part in parts]
        ws = RasterWorkspace(outputs=True)
        for workspace in (None, ws, ws):
            virtual, flags = parts_vertices(parts, tess.points, tess.corner_index,
                                            workspace)
            assert virtual.shape == (len(parts), len(tess.points), 3)
            for p, (v, f) in enumerate(want):
                assert virtual[p].tobytes() == v.tobytes()
                assert flags[p].tobytes() == f.tobytes()
        # in float32 (what the technique asks for, its draw's gather's rounding)
        virtual, flags = parts_vertices(parts, tess.points, tess.corner_index, ws, np.float32)
        for p, (v, f) in enumerate(want):
            assert virtual[p].tobytes() == v.astype(np.float32).tobytes()
            assert flags[p].tobytes() == f.tobytes()
        # the parts as the technique makes them (explosion_group: every part's focus,
        # extent and, in parts_vertices, map set-up in one kernel call; partsetup.py)
        counts, boxes = mirror_boxes(primary.frame.surface, scene.n_objects,
                                     scene.mirrors.count)
        together, _ = explosion_group(cfg.technique, scene, primary, 0, cam,
                                      state.scene_points, state.shapes, state.views,
                                      tuple(int(b) for b in boxes[0]), ws)
        assert len(together) == len(parts)
        assert all(part.together is not None for part in together)
        for a, b in zip(together, parts, strict=True):
            assert a.screen.tobytes() == b.screen.tobytes()
            assert a.flip.tobytes() == b.flip.tobytes()
            assert [np.asarray(x).tobytes() for x in a.build_args[1:7]] == \
                [np.asarray(x).tobytes() for x in b.build_args[1:7]]
        virtual, flags = parts_vertices(together, tess.points, tess.corner_index, ws)
        for p, (v, f) in enumerate(want):
            assert virtual[p].tobytes() == v.tobytes()
            assert flags[p].tobytes() == f.tobytes()
        # the parts' face tables: the shape's own rows where the parts run p0, p0 + 1, ..
        for chosen in (parts, parts[1:4], parts[::2], parts[::-1]):
            tables = _locals(chosen)
            assert tables.tobytes() == np.stack([q.view.local for q in chosen]).tobytes()
        assert _locals(parts[1:4]).base is parts[0].view.tables
    finally:
        numba.set_num_threads(before)


@compiled_only
@pytest.mark.parametrize("threads", [1, 2])
def test_part_passes_together_give_the_frame_part_by_part(threads, monkeypatch):
    """A mesh reflector of several parts drawn together (partpasses.draw_parts: one label
    image, rasterize_passes, one shading, compose_passes) gives the frame's bytes drawn
    part by part (draw_virtual and add_reflection, each part's stencil), frame after
    frame."""
    import numba

    import reflectcli.techniques.virtual.technique as module

    before = numba.get_num_threads()
    try:
        _, scene, cam, technique, state = _mask_frame(threads)
        together = [technique.render(state, 0, cam).rgb.copy() for _ in range(2)]
        assert together[0].tobytes() == together[1].tobytes()
        monkeypatch.setattr(module, "explosion_group", lambda *args, **kwargs: None)
        apart = technique.render(state, 0, cam)
        assert apart.stats["reflector_parts"] > 4
        assert apart.rgb.tobytes() == together[0].tobytes()
    finally:
        numba.set_num_threads(before)


@compiled_only
@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("name", ["four-spheres", "hall-of-mirrors", "cylinder-room"])
def test_primary_and_boxes_match_render_primary(name, threads):
    """The virtual frame's primary pass (primary_and_boxes: merge, shading, mirror boxes
    and sphere labels in one region) gives render_primary's frame and triangle ids,
    mirror_boxes' counts and boxes, and pass_labels' labels and stencil (every pixel),
    frame after frame into the same workspace, at 96 x 80."""
    import numba
    from conftest import SCENES

    from reflectcli.camera import camera_from_config
    from reflectcli.loading import load_config
    from reflectcli.raster.primary import render_primary
    from reflectcli.raster.rasterize import RasterWorkspace
    from reflectcli.scene.build import build_scene
    from reflectcli.virtual.primary import primary_and_boxes

    before = numba.get_num_threads()
    try:
        numba.set_num_threads(threads)
        path = str(SCENES / f"{name}.toml")
        cfg, _ = load_config(path, ["camera.width=96", "camera.height=80"], "virtual")
        scene = build_scene(cfg, path)
        m = scene.mirrors.count
        label_of = np.zeros(m, np.uint8)
        label_of[::2] = np.arange(1, len(label_of[::2]) + 1)
        ws = RasterWorkspace()
        labels = np.full((80, 96), 77, np.uint8)
        stencil = np.ones((80, 96), np.bool_)
        for frame_index in (0, 1, 0):
            cam = camera_from_config(cfg.camera, frame_index)
            want = render_primary(scene, frame_index, cam)
            counts, boxes = naive_mirror_boxes(want.frame.surface, scene.n_objects, m)
            got, got_counts, got_boxes, labelled = primary_and_boxes(
                scene, frame_index, cam, ws, label_of, labels, stencil)
            assert labelled
            for field in ("rgb", "depth", "surface", "mirror_mask"):
                assert getattr(got.frame, field).tobytes() == getattr(want.frame, field).tobytes()
            assert got.buffers.triangle.tobytes() == want.buffers.triangle.tobytes()
            assert got.flags.tobytes() == want.flags.tobytes()
            assert np.array_equal(got_counts, counts) and np.array_equal(got_boxes, boxes)
            want_labels = np.zeros((80, 96), np.uint8)
            want_stencil = np.zeros((80, 96), np.bool_)
            compose.pass_labels(want.frame.surface, want.buffers.depth, scene.n_objects,
                                label_of, 0, 80, 0, 96, want_labels, want_stencil,
                                np.zeros((80, 96), np.float32))
            assert labels.tobytes() == want_labels.tobytes()
            assert stencil.tobytes() == want_stencil.tobytes()
    finally:
        numba.set_num_threads(before)


@compiled_only
@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("name", ["four-spheres", "four-spheres-lit"])
def test_spheres_drawn_together_give_the_frame_sphere_by_sphere(name, threads, monkeypatch):
    """Sphere mirrors drawn together (together.draw_spheres: labels from the primary pass,
    or from pass_labels when they are not the group's; rasterize_passes; one region
    shading, filling cracks and adding the reflections, `_shade_compose`) give the
    frame's bytes drawn sphere by sphere (draw_virtual and add_reflection), frame after
    frame, at 128 x 112."""
    import numba
    from conftest import SCENES

    import reflectcli.techniques.virtual.technique as module
    from reflectcli.camera import camera_from_config
    from reflectcli.loading import load_config
    from reflectcli.scene.build import build_scene

    before = numba.get_num_threads()
    try:
        numba.set_num_threads(threads)
        path = str(SCENES / f"{name}.toml")
        cfg, _ = load_config(path, ["camera.width=128", "camera.height=112"], "virtual")
        scene = build_scene(cfg, path)
        cam = camera_from_config(cfg.camera, 0)
        technique = module.Virtual(cfg.technique)
        state = technique.prepare(scene)
        together = [technique.render(state, 0, cam).rgb.copy() for _ in range(2)]
        assert together[0].tobytes() == together[1].tobytes()
        state.sphere_labels = np.zeros_like(state.sphere_labels)  # labels not the group's
        relabelled = technique.render(state, 0, cam)
        assert relabelled.rgb.tobytes() == together[0].tobytes()
        monkeypatch.setattr(module, "worth_together", lambda boxes: False)
        apart = technique.render(state, 0, cam)
        assert apart.stats["reflector_parts"] == 4
        assert apart.rgb.tobytes() == together[0].tobytes()
    finally:
        numba.set_num_threads(before)


@compiled_only
def test_sphere_blocks_give_the_one_at_a_time_search_s_bytes():
    """Each visible point's virtual vertex from the blocks (VECTOR_STEPS side by side, the
    points left packed and stepped side by side, the last one at a time) is the very bytes
    of `_circle_reflection`'s search for that point alone (every step the same floating-
    point operations), mirrored by the same arithmetic; on points of which some need many
    steps (near the silhouette, far behind, close to the sphere)."""
    import math

    from numba import njit

    @njit
    def one_at_a_time(points, eye, center, r, out, visible):
        ex, ey, ez = eye[0] - center[0], eye[1] - center[1], eye[2] - center[2]
        le = math.sqrt(ex * ex + ey * ey + ez * ez)
        xx, xy, xz = ex / le, ey / le, ez / le
        for i in range(points.shape[0]):
            qx = points[i, 0] - center[0]
            qy = points[i, 1] - center[1]
            qz = points[i, 2] - center[2]
            lq = math.sqrt(qx * qx + qy * qy + qz * qz)
            a = qx * xx + qy * xy + qz * xz
            yx, yy, yz = qx - a * xx, qy - a * xy, qz - a * xz
            b = math.sqrt(yx * yx + yy * yy + yz * yz)
            visible[i] = lq > r and b >= 1e-12 * lq
            if not visible[i]:
                continue
            yx, yy, yz = yx / b, yy / b, yz / b
            ct, st = circle._circle_reflection(le, a, b, r)
            nx, ny, nz = ct * xx + st * yx, ct * xy + st * yy, ct * xz + st * yz
            dist = qx * nx + qy * ny + qz * nz - r
            out[i, 0] = points[i, 0] - 2.0 * dist * nx
            out[i, 1] = points[i, 1] - 2.0 * dist * ny
            out[i, 2] = points[i, 2] - 2.0 * dist * nz

    rng = np.random.default_rng(21)
    eye, pts = circle_cases(rng)
    center = np.array([0.1, -0.2, 0.05])
    side = rng.normal(size=(400, 3))
    side /= np.linalg.norm(side, axis=1)[:, None]
    pts = np.ascontiguousarray(np.concatenate([
        pts, center + side * rng.uniform(1.0001, 1.05, (400, 1)),  # close to the sphere
        center + side * rng.uniform(20.0, 200.0, (400, 1)),  # far
        rng.normal(size=(3 * circle.BLOCK, 3)) * 4.0]))
    got, hidden = circle.sphere_virtual_vertices(pts, eye, center, 1.0)
    want = np.empty_like(pts)
    visible = np.empty(len(pts), np.bool_)
    one_at_a_time(pts, eye, center, 1.0, want, visible)
    keep = visible & ~hidden
    assert keep.sum() > len(pts) // 2
    assert got[keep].tobytes() == want[keep].tobytes()
