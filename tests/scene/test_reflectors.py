"""Curved reflector meshes (extrusion, spherical cap), the mask asset, and their bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from reflectcli.config.mirrors import CapMirror, ExtrusionMirror
from reflectcli.errors import Problems
from reflectcli.geometry import trs_matrix
from reflectcli.loading import load_config
from reflectcli.scene.build import build_scene
from reflectcli.scene.mesh_file import load_mesh_file
from reflectcli.scene.mirrors import cap_mesh, extrusion_mesh, extrusion_profile, mirror_mesh
from reflectcli.scene.types import MESH

MASK = Path(__file__).resolve().parents[2] / "scenes" / "assets" / "mask.ply"

# an arc of the circle of radius 3 centred at (0, -C) in (x, z), running toward -x, so its
# front (left of the direction seen from +y) is +z, the convex side
R = 3.0
C = np.sqrt(R**2 - 0.36)
ARC_PHI = np.linspace(1.0, -1.0, 9) * np.arcsin(0.6 / R)  # evenly spaced along the arc
ARC = np.stack([R * np.sin(ARC_PHI), R * np.cos(ARC_PHI) - C], axis=1)


def extrusion(profile=ARC, **kw) -> ExtrusionMirror:
    fields = dict(
        name="tv",
        shape="extrusion",
        profile=[tuple(p) for p in profile],
        height=0.9,
        subdivisions=3,
        transform={"translate": (1.0, 2.0, -3.0), "rotate": (0.0, 40.0, 10.0)},
    )
    fields.update(kw)
    return ExtrusionMirror.model_validate(fields)


def cap(**kw) -> CapMirror:
    fields = dict(
        name="dish",
        shape="cap",
        center=(0.5, 1.0, -2.0),
        radius=2.0,
        axis=(0.0, 0.6, -0.8),
        angle=35.0,
        segments=48,
    )
    fields.update(kw)
    return CapMirror.model_validate(fields)


def to_local(points: np.ndarray, frame: np.ndarray) -> np.ndarray:
    inv = np.linalg.inv(frame)
    return points @ inv[:3, :3].T + inv[:3, 3]


def assert_fronts_agree(mesh) -> None:
    """Unit shading normals on the front side of the winding (front = reflecting side)."""
    assert np.allclose(np.linalg.norm(mesh.normals, axis=2), 1.0)
    assert mesh.areas().min() > 0
    dots = np.einsum("fck,fk->fc", mesh.normals, mesh.face_normals())
    assert dots.min() > 0.9


# ---------------------------------------------------------------- extrusion


def test_extrusion_vertices_lie_on_the_profile_and_height():
    m = extrusion()
    mesh = extrusion_mesh(m)
    assert mesh.triangle_count == 2 * (len(ARC) - 1) * 3
    _, _, frame, height = extrusion_profile(m)
    local = to_local(mesh.corners.reshape(-1, 3), frame)
    # every corner is a profile point at one of the 4 row heights
    d = np.linalg.norm(local[:, None, [0, 2]] - ARC[None], axis=2)
    assert d.min(axis=1).max() < 1e-9
    rows = np.linspace(0.0, 0.9, 4)
    assert np.abs(local[:, 1, None] - rows[None]).min(axis=1).max() < 1e-9
    assert height == 0.9
    # and every profile point and row appears
    assert (d.min(axis=0) < 1e-9).all()


def test_extrusion_normals_are_smooth_and_face_the_left_of_the_profile():
    m = extrusion()
    mesh = extrusion_mesh(m)
    assert_fronts_agree(mesh)
    _, _, frame, _ = extrusion_profile(m)
    local_n = mesh.normals.reshape(-1, 3) @ frame[:3, :3]  # rotation only: inverse = transpose
    assert np.abs(local_n[:, 1]).max() < 1e-12  # perpendicular to the extrusion axis
    assert local_n[:, 2].min() > 0.0  # the arc runs toward -x: front is +z
    # averaged segment normals of evenly spaced arc points are the circle's radial normals
    # (but at the two ends, which take their one segment's normal)
    local_p = to_local(mesh.corners.reshape(-1, 3), frame)
    radial = np.stack([local_p[:, 0], local_p[:, 2] + C], axis=1) / R
    inner = np.abs(local_p[:, 0]) < 0.59
    assert inner.sum() > 0.5 * len(inner)
    assert np.abs(local_n[inner][:, [0, 2]] - radial[inner]).max() < 1e-9


def test_extrusion_profile_for_the_technique():
    m = extrusion(profile=[*ARC[:3], ARC[2], *ARC[3:]])  # a repeated point is dropped
    points, normals, frame, height = extrusion_profile(m)
    assert points.shape == normals.shape == (len(ARC), 2)
    assert np.allclose(points, ARC)
    assert np.allclose(np.linalg.norm(normals, axis=1), 1.0)
    # end points take their one segment's normal: (dz, -dx) / |d|
    d = ARC[1] - ARC[0]
    assert np.allclose(normals[0], np.array([d[1], -d[0]]) / np.linalg.norm(d))
    assert np.allclose(frame, trs_matrix((1.0, 2.0, -3.0), (0.0, 40.0, 10.0), 1.0))
    assert height == 0.9


def test_reversed_profile_faces_the_other_way():
    a = extrusion_profile(extrusion())[1]
    b = extrusion_profile(extrusion(profile=ARC[::-1]))[1]
    assert np.allclose(a, -b[::-1])


def test_straight_extrusion_is_a_flat_rectangle():
    m = extrusion(
        profile=[(1.0, 0.0), (-1.0, 0.0)], subdivisions=1, transform={"translate": (0.0, 0.0, 0.0)}
    )
    mesh = extrusion_mesh(m)
    assert mesh.triangle_count == 2
    assert np.allclose(mesh.normals.reshape(-1, 3), [0.0, 0.0, 1.0])
    assert np.isclose(mesh.areas().sum(), 2.0 * 0.9)


# ---------------------------------------------------------------- cap


@pytest.mark.parametrize("concave", [False, True])
def test_cap_vertices_on_the_sphere_within_the_angle(concave):
    m = cap(concave=concave)
    mesh = cap_mesh(m)
    center = np.array(m.center)
    axis = np.array(m.axis) / np.linalg.norm(m.axis)
    p = mesh.corners.reshape(-1, 3) - center
    assert np.allclose(np.linalg.norm(p, axis=1), m.radius)
    polar = np.degrees(np.arccos(np.clip(p @ axis / m.radius, -1, 1)))
    assert polar.max() == pytest.approx(35.0)
    assert polar.min() == pytest.approx(0.0, abs=1e-6)  # the pole is in
    rings = int(np.ceil(48 * 35.0 / 360.0))
    assert mesh.triangle_count == 48 * (2 * rings - 1)


def test_convex_cap_normals_point_away_from_the_center():
    m = cap()
    mesh = cap_mesh(m)
    assert_fronts_agree(mesh)
    outward = (mesh.corners - np.array(m.center)) / m.radius
    assert np.allclose(mesh.normals, outward)


def test_concave_cap_normals_point_toward_the_center():
    m = cap(concave=True)
    mesh = cap_mesh(m)
    assert_fronts_agree(mesh)
    inward = (np.array(m.center) - mesh.corners) / m.radius
    assert np.allclose(mesh.normals, inward)
    # the winding's front faces the center too
    to_center = np.array(m.center) - mesh.corners.mean(axis=1)
    assert (np.einsum("fk,fk->f", mesh.face_normals(), to_center) > 0).all()


def test_hemisphere_cap_area():
    mesh = cap_mesh(cap(angle=90.0, segments=256))
    assert mesh.areas().sum() == pytest.approx(2 * np.pi * 4.0, rel=2e-3)


def test_curved_reflectors_are_traced_as_triangles():
    for m in (extrusion(), cap(concave=True)):
        mesh, exact = mirror_mesh(m, "scene.toml")
        assert exact and mesh.triangle_count > 0


# ---------------------------------------------------------------- the mask asset


def test_mask_asset_has_convex_and_concave_pieces():
    import trimesh

    tm = trimesh.load(MASK, force="mesh")
    assert 6000 <= len(tm.faces) <= 10000
    mesh = load_mesh_file(MASK)
    assert mesh.triangle_count == len(tm.faces)
    assert mesh.face_normals()[:, 2].min() > 0  # front = +z everywhere
    assert mesh.normals[..., 2].min() > 0
    # discrete mean curvature by the umbrella operator: (mean of neighbours - v) . n is
    # negative where the surface bends away from its normal (convex), positive in hollows
    v = np.asarray(tm.vertices)
    n = np.asarray(tm.vertex_normals)
    boundary = np.unique(tm.edges_sorted[trimesh.grouping.group_rows(tm.edges_sorted, 1)])
    lap = np.array([v[nb].mean(axis=0) - v[i] for i, nb in enumerate(tm.vertex_neighbors)])
    h = np.einsum("ij,ij->i", lap, n)
    interior = np.setdiff1d(np.arange(len(v)), boundary)
    scale = np.median(tm.edges_unique_length) ** 2
    convex = (h[interior] < -0.02 * scale).mean()
    concave = (h[interior] > 0.02 * scale).mean()
    assert convex > 0.2 and concave > 0.05, (convex, concave)

    def at(x, y):
        return h[np.argmin(np.hypot(v[:, 0] - x, v[:, 1] - y))]

    for side in (-1, 1):
        assert at(side * 0.5, -0.4) < 0  # cheeks
        assert at(side * 0.42, 0.4) > 0  # eye sockets
    assert at(0.0, 0.1) < 0  # nose ridge


# ---------------------------------------------------------------- config: bad input and build

SCENE = """
[scene]
name = "tiny"
[camera]
eye = [0.0, 1.0, 4.0]
target = [0.0, 1.0, 0.0]
width = 32
height = 32
[materials.grey]
kind = "solid"
color = [0.5, 0.5, 0.5]
[[objects]]
name = "floor"
shape = "quad"
corners = [[-3, 0, 3], [3, 0, 3], [3, 0, -3], [-3, 0, -3]]
material = "grey"
"""

EXTRUSION = """
[[mirrors]]
name = "screen"
shape = "extrusion"
profile = {profile}
height = 0.9
"""

CAP = """
[[mirrors]]
name = "dish"
shape = "cap"
center = [0.0, 1.0, 1.0]
radius = 2.0
axis = {axis}
angle = 35.0
concave = true
"""


def load(tmp_path, text):
    path = tmp_path / "scene.toml"
    path.write_text(SCENE + text)
    return load_config(str(path))


@pytest.mark.parametrize(
    "profile, message",
    [
        ("[[0.5, 0.0]]", "at least 2 distinct points"),
        ("[]", "at least 2 distinct points"),
        ("[[0.5, 0.0], [0.5, 0.0]]", "at least 2 distinct points"),
        ("[[0.5, 0.0], [-0.5, 0.0], [0.5, 0.0]]", "turns back on itself"),
    ],
)
def test_bad_profile_is_one_problem(tmp_path, profile, message):
    with pytest.raises(Problems) as e:
        load(tmp_path, CAP.format(axis="[0, 0, -1]") + EXTRUSION.format(profile=profile))
    (problem,) = e.value.problems
    assert problem.field == "mirrors.1.profile"
    assert message in problem.message
    assert problem.file.endswith("scene.toml")


def test_zero_cap_axis_is_one_problem(tmp_path):
    with pytest.raises(Problems) as e:
        load(tmp_path, CAP.format(axis="[0, 0, 0]"))
    (problem,) = e.value.problems
    assert (problem.field, problem.message) == ("mirrors.0.axis", "must not be zero")


@pytest.mark.parametrize("field, value", [("angle", "0.0"), ("angle", "181.0"), ("radius", "-1.0")])
def test_cap_ranges(tmp_path, field, value):
    text = CAP.format(axis="[0, 0, -1]").replace(f"{field} = ", f"{field} = {value} #")
    with pytest.raises(Problems) as e:
        load(tmp_path, text)
    (problem,) = e.value.problems
    assert problem.field == f"mirrors.0.{field}"


def test_scene_with_curved_reflectors_builds(tmp_path):
    text = CAP.format(axis="[0, 0, -1]") + EXTRUSION.format(profile=ARC.tolist())
    cfg, _ = load(tmp_path, text)
    scene = build_scene(cfg, str(tmp_path / "scene.toml"))
    assert scene.mirrors.kind.tolist() == [MESH, MESH]
    geometry = scene.geometry(0)
    assert geometry.mirror_exact.all()
    per_mirror = np.bincount(geometry.mirror_tris.surface - scene.n_objects)
    assert per_mirror.tolist() == [
        cap_mesh(cfg.mirrors[0]).triangle_count,
        extrusion_mesh(cfg.mirrors[1]).triangle_count,
    ]


def test_flat_extrusion_reflects_like_a_quad_mirror(tmp_path):
    """A straight extrusion is a planar mirror: the ray tracer must show the same image as
    for the equivalent analytic quad mirror."""
    from conftest import psnr, render_frame

    room = """
[materials.checker]
kind = "checker"
color0 = [0.1, 0.1, 0.1]
color1 = [0.9, 0.8, 0.2]
scale = [6, 6]
[[objects]]
name = "room"
shape = "room"
min = [-3.0, -0.5, -3.0]
max = [3.0, 3.0, 6.0]
material = "checker"
[technique]
name = "raytrace"
max_depth = 2
"""
    flat = EXTRUSION.format(profile="[[0.8, 0.0], [-0.8, 0.0]]") + (
        "transform = { translate = [0.0, 0.4, -1.0], rotate = [0.0, 20.0, 0.0] }\n"
    )
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    a.write_text(SCENE + room + flat)
    frame_matrix = trs_matrix((0.0, 0.4, -1.0), (0.0, 20.0, 0.0), 1.0)
    local = np.array([[-0.8, 0, 0, 1], [0.8, 0, 0, 1], [0.8, 0.9, 0, 1], [-0.8, 0.9, 0, 1]])
    corners = (local @ frame_matrix.T)[:, :3]
    # corners in the order whose front (p10 - p00) x (p01 - p00) is the extrusion's (local +z)
    b.write_text(
        SCENE
        + room
        + '[[mirrors]]\nname = "screen"\nshape = "quad"\ncorners = '
        + str(corners.tolist())
        + "\n"
    )
    size = ("camera.width=96", "camera.height=96")
    fa, _ = render_frame(a, overrides=size)
    fb, _ = render_frame(b, overrides=size)
    assert fa.mirror_mask.sum() > 300  # the mirror is well in view
    assert (fa.mirror_mask != fb.mirror_mask).sum() <= 8  # silhouette pixels at most
    both = fa.mirror_mask & fb.mirror_mask
    assert psnr(fa.rgb[both], fb.rgb[both]) > 40.0
