"""Degenerate geometry and sizes past the documented limits: one line from validate and render
alike, nothing written; nothing non-finite ever reaches an output file."""

from __future__ import annotations

import numpy as np
import pytest

from reflectcli.errors import Problems
from reflectcli.output.finite import check_finite

from .common import TINY, assert_one_line, chdir, check_bad, invoke, write

LAMBERT = TINY.replace('name = "tiny"', 'name = "tiny"\nshading = "lambert"')

CASES = [  # (appended TOML, expected field)
    ('\n[[lights]]\nkind = "directional"\ndirection = [0, 0, 0]\n', "lights.0.direction"),
    ('\n[[objects]]\nname = "z"\nshape = "box"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\n'
     'material = "red"\ntransform = { scale = 0.0 }\n', "objects.1.transform.scale"),
    ('\n[[objects]]\nname = "z"\nshape = "box"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\n'
     'material = "red"\ntransform = { scale = [1.0, 0.0, 1.0] }\n', "objects.1.transform.scale"),
    ('\n[[objects]]\nname = "q"\nshape = "quad"\nmaterial = "red"\n'
     'corners = [[0, 0, 0], [0, 0, 0], [1, 1, 0], [0, 1, 0]]\n', "objects.1.corners"),
    ('\n[[objects]]\nname = "far"\nshape = "sphere"\nmaterial = "red"\n'
     'transform = { translate = [1e16, 0, 0] }\n', "objects.1.transform.translate"),
    ('\n[[mirrors]]\nname = "m2"\nshape = "quad"\n'
     'corners = [[1e16, 0, 0], [0, 0, 0], [1, 1, 0], [0, 1, 0]]\n', "mirrors.1.corners"),
]


@pytest.mark.parametrize(("extra", "field"), CASES)
def test_degenerate_scene_items(tmp_path, extra, field):
    scene = write(tmp_path, "s.toml", LAMBERT + extra)
    with chdir(tmp_path):
        check_bad(scene, f"s.toml: {field}:")


@pytest.mark.parametrize(("key", "value"), [
    ("near", "1e-30"), ("fov_y", "5e-324"), ("width", "100000"), ("eye", "[1e16, 0, 0]"),
    ("up", "[0, 0, 0]"),
])
def test_degenerate_camera(tmp_path, key, value):
    text = TINY.replace("width = 16\n", f"width = 16\n{key} = {value}\n") if key not in (
        "width", "eye") else TINY.replace(f"{key} = ", f"{key} = {value}\nxx_{key} = ", 1)
    text = "\n".join(line for line in text.splitlines() if not line.startswith("xx_"))
    scene = write(tmp_path, "s.toml", text)
    with chdir(tmp_path):
        check_bad(scene, f"s.toml: camera.{key}:")


def test_sizes_past_the_limits(tmp_path):
    path = ('\n[camera.path]\nframes = 10000000\n'
            'keys = [{ eye = [0, 1, 3], target = [0, 0, 0] }]\n')
    text = TINY.replace("height = 12\n", "height = 12\n" + path)
    scene = write(tmp_path, "frames.toml", text)
    with chdir(tmp_path):
        check_bad(scene, "frames.toml: camera.path.frames: must be <= 100000")
        scene = write(tmp_path, "seg.toml", TINY.replace("segments = 8", "segments = 100000"))
        check_bad(scene, "seg.toml: objects.0.segments: must be <=")
        scene = write(tmp_path, "tri.toml", TINY.replace("segments = 8", "segments = 4096")
                      + '\n[[objects]]\nname = "t"\nshape = "teapot"\nsubdivisions = 64\n'
                        'material = "red"\n[[objects]]\nname = "c"\nshape = "clutter"\n'
                        'triangles = 20000000\nmin = [0, 0, 0]\nmax = [1, 1, 1]\n'
                        'material = "red"\n')
        check_bad(scene, "tri.toml: objects:", "the limit is 20,000,000")


def test_memory_estimate_before_allocating(tmp_path):
    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "dprm"\n'
                  '[technique.maps]\ncount = 4096\nresolution = 8192\nlayout = "fibonacci"\n')
    with chdir(tmp_path):
        check_bad(scene, "s.toml: technique:", "of memory;", "available")


def test_nothing_non_finite_is_written():
    good = {"R": np.zeros((2, 2)), "Z": np.full((2, 2), np.inf)}
    check_finite(good, "s.toml", 0)
    with pytest.raises(Problems, match="channel R has 1 non-finite"):
        check_finite({"R": np.array([[0.0, np.nan]])}, "s.toml", 3)


def test_huge_color_is_refused_not_rendered_to_nan(tmp_path):
    """fuzz seed 105258: a color component of 1e308 gave NaN pixels on the mask scene."""
    scene = write(tmp_path, "s.toml", LAMBERT.replace("color = [0.8, 0.1, 0.1]",
                                                      "color = [0.8, 0.1, 1e308]")
                  + '\n[[lights]]\nkind = "point"\nposition = [0, 3, 2]\n')
    with chdir(tmp_path):
        check_bad(scene, "s.toml: materials.red.color: numbers must be within")


def test_envmap_without_objects_renders(tmp_path):
    """fuzz seed 105598: envmap's default proxy box over no objects was a traceback."""
    from .common import invoke

    text = TINY.split("[[objects]]")[0] + "[[mirrors]]" + TINY.split("[[mirrors]]")[1]
    scene = write(tmp_path, "s.toml", text + '\n[technique]\nname = "envmap"\nresolution = 8\n')
    with chdir(tmp_path):
        result = invoke("render", scene, "--out", tmp_path / "o", "--cache", tmp_path / "c")
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize("fov", ["170.001", "179.99", "179.9999999"])
def test_field_of_view_too_wide_to_show_anything(tmp_path, fov):
    """fov_y = 179.99 validated and rendered background only: the limit is 170 degrees."""
    scene = write(tmp_path, "s.toml", TINY.replace("width = 16\n", f"width = 16\nfov_y = {fov}\n"))
    with chdir(tmp_path):
        check_bad(scene, "s.toml: camera.fov_y: must be <= 170")
    key = ('\n[camera.path]\nframes = 2\n'
           f'keys = [{{ eye = [0, 1, 3], target = [0, 0, 0], fov_y = {fov} }}]\n')
    scene = write(tmp_path, "k.toml", TINY.replace("height = 12\n", "height = 12\n" + key))
    with chdir(tmp_path):
        check_bad(scene, "k.toml: camera.path.keys.0.fov_y: must be <= 170")


@pytest.mark.parametrize(("box", "field"), [
    ("proxy_min = [-1, 0, -1]\nproxy_max = [1, -1, 1]\n", "technique.proxy_min"),
    ("proxy_min = [-1, 0, -1]\n", "technique.proxy_max"),
])
def test_envmap_proxy_box_turned_inside_out_or_half_given(tmp_path, box, field):
    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "envmap"\nresolution = 8\n'
                  + box)
    with chdir(tmp_path):
        check_bad(scene, f"s.toml: {field}:")


def test_number_of_lights_is_limited(tmp_path):
    """90,000 lights validated and took 5 s a 160x120 frame."""
    lights = '\n[[lights]]\nkind = "point"\nposition = [0, 3, 2]\n' * 257
    scene = write(tmp_path, "s.toml", LAMBERT + lights)
    with chdir(tmp_path):
        check_bad(scene, "s.toml: lights: 257 lights; the limit is 256")


def test_distmap_layers_count_in_the_memory_estimate(tmp_path, monkeypatch):
    """resolution 4096 with 8 layers (about 100 GB) validated on a 22 GiB machine."""
    from reflectcli.config import memory

    monkeypatch.setattr(memory, "available_bytes", lambda: 22 << 30)
    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "distmap"\n'
                  "resolution = 4096\nlayers = 8\n")
    with chdir(tmp_path):
        check_bad(scene, "s.toml: technique: this render needs about", "22.0 GiB is available")


MESH_OBJECT = '\n[[objects]]\nname = "m"\nshape = "mesh"\npath = "m.obj"\nmaterial = "red"\n'


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize(("x", "limit"), [("1e7", "1e+06"), ("1e30", "1e+09"),
                                          ("1e300", "1e+09")])
def test_mesh_coordinates_past_the_limit(tmp_path, x, limit):
    """A mesh with `v 1e30 0 0` (or 1e7) and no `fit` validated and rendered; trimesh's
    overflow warnings came on stderr besides (an error here). Past 1e9 even `fit` cannot
    help (the normals overflow)."""
    (tmp_path / "m.obj").write_text(f"v {x} 0 0\nv 0 1 0\nv 0 0 1\nv -{x} 0 0\nf 1 2 3\n"
                                    "f 4 2 3\n")
    scene = write(tmp_path, "s.toml", TINY + MESH_OBJECT)
    with chdir(tmp_path):
        check_bad(scene, "s.toml: objects.1.path:", "coordinates", limit)
    scene = write(tmp_path, "m.toml", TINY + '\n[[mirrors]]\nname = "m"\nshape = "mesh"\n'
                  'path = "m.obj"\n')
    with chdir(tmp_path):
        check_bad(scene, "m.toml: mirrors.1.path:", "coordinates", limit)


WORLD_CASES = [  # (appended TOML, expected field): each field within 1e6, the world not
    ('\n[[objects]]\nname = "big"\nshape = "sphere"\nradius = 1e6\nsegments = 8\n'
     'material = "red"\ntransform = { scale = 1e6 }\n', "objects.1.transform"),
    ('\n[[objects]]\nname = "t"\nshape = "teapot"\nmaterial = "red"\n'
     'transform = { translate = [9e5, 0, 0], scale = 1e5 }\n', "objects.1.transform"),
    ('\n[[objects]]\nname = "b"\nshape = "sphere"\nradius = 3.0\nsegments = 8\n'
     'material = "red"\nmotion = [{ frame = 0 }, { frame = 1, rotate = [0, 90, 0], '
     'scale = 5e5 }]\n', "objects.1.motion"),
    ('\n[[objects]]\nname = "r"\nshape = "torus"\nmajor_radius = 1e6\nminor_radius = 1e6\n'
     'material = "red"\n', "objects.1.major_radius"),
    ('\n[[mirrors]]\nname = "s"\nshape = "sphere"\ncenter = [1e6, 0, 0]\nradius = 1e6\n',
     "mirrors.1.radius"),
]


@pytest.mark.parametrize(("toml", "field"), WORLD_CASES)
def test_coordinate_limit_holds_in_world_space(tmp_path, toml, field):
    """A sphere of radius 1e6 scaled by 1e6 rendered: the limit was checked per field,
    not on the geometry after its transform."""
    scene = write(tmp_path, "s.toml", TINY + toml)
    with chdir(tmp_path):
        check_bad(scene, f"s.toml: {field}: world-space coordinates reach", "past +-1e+06")


def test_world_coordinate_limit_names_the_file_the_transform_came_from(tmp_path):
    teapot = '\n[[objects]]\nname = "t"\nshape = "teapot"\nmaterial = "red"\n'
    write(tmp_path, "part.toml", TINY + teapot + "transform = { scale = 1e6 }\n")
    scene = write(tmp_path, "s.toml", 'include = ["part.toml"]\n')
    with chdir(tmp_path):
        check_bad(scene, "part.toml: objects.1.transform: world-space coordinates reach")
        write(tmp_path, "part.toml", TINY + teapot)
        result = invoke("render", scene, "--out", tmp_path / "o", "--frames", "0",
                        "--set", "objects.t.transform.scale=1e6")
    assert_one_line(result, "--set: objects.1.transform: world-space coordinates reach")
    assert not (tmp_path / "o").exists()


def test_a_mesh_file_refused_at_build_names_the_include_it_came_from(tmp_path):
    """A mesh file refused when the scene is built (here: coordinates past 1e9) is named
    with the file its object or mirror came from, as the world-space limit is; the line
    named the including scene."""
    (tmp_path / "m.obj").write_text("v 1e30 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n")
    scene = write(tmp_path, "s.toml", 'include = ["part.toml"]\n')
    for section in ("objects", "mirrors"):
        extra = MESH_OBJECT if section == "objects" else (
            '\n[[mirrors]]\nname = "m"\nshape = "mesh"\npath = "m.obj"\n')
        write(tmp_path, "part.toml", TINY + extra)
        with chdir(tmp_path):
            check_bad(scene, f"part.toml: {section}.1.path:", "coordinates", "1e+09")


def test_mesh_in_millimetres_scaled_by_its_transform_renders(tmp_path):
    """A mesh with coordinates past 1e6 in its file, brought into the scene by its
    object's transform (no `fit`), was refused though its world-space geometry is small."""
    from .common import files_under

    (tmp_path / "m.obj").write_text("v 2e6 0 0\nv 0 2e6 0\nv 0 0 2e6\nf 1 2 3\n")
    scene = write(tmp_path, "s.toml", TINY + MESH_OBJECT
                  + "transform = { scale = 1e-6 }\n")
    mirror = write(tmp_path, "m.toml", TINY + '\n[[mirrors]]\nname = "m"\nshape = "mesh"\n'
                   'path = "m.obj"\ntransform = { scale = 1e-6 }\n')
    with chdir(tmp_path):
        for path in (scene, mirror):
            result = invoke("validate", path)
            assert result.exit_code == 0, result.output
            out = tmp_path / f"out-{path.stem}"
            result = invoke("render", path, "--out", out, "--frames", "0")
            assert result.exit_code == 0, result.output
            assert any(f.endswith("frame_0000.exr") for f in files_under(out))


def test_mesh_in_miles_fitted_into_the_scene_is_fine(tmp_path):
    from .common import invoke

    (tmp_path / "m.obj").write_text("v 1e7 0 0\nv 0 1e7 0\nv 0 0 1e7\nf 1 2 3\n")
    scene = write(tmp_path, "s.toml", TINY + MESH_OBJECT + "fit = { center = [0, 0, 0], "
                  "size = 1.0 }\n")
    with chdir(tmp_path):
        result = invoke("validate", scene)
    assert result.exit_code == 0, result.output
