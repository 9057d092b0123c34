"""TOML loading: includes, section files, --set overrides, and errors naming file and field."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from reflectcli.errors import Problems
from reflectcli.loading import load_config

CAMERA = """
[camera]
eye = [0.0, 1.0, 3.0]
target = [0.0, 0.5, 0.0]
width = 100
height = 80
"""

MATERIALS = """
[materials.red]
kind = "solid"
color = [0.8, 0.1, 0.1]
"""

OBJECTS = """
[[objects]]
name = "ball"
shape = "sphere"
radius = 0.5
material = "red"

[[objects]]
name = "teapot"
shape = "teapot"
subdivisions = 2
material = "red"
"""

MIRRORS = """
[[mirrors]]
name = "floor"
shape = "quad"
corners = [[-2, 0, 2], [2, 0, 2], [2, 0, -2], [-2, 0, -2]]
reflectance = 0.5
"""

SCENE = '[scene]\nname = "tiny"\n' + CAMERA + MATERIALS + OBJECTS + MIRRORS


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text))
    return path


@pytest.fixture
def here(tmp_path, monkeypatch) -> Path:
    """Work inside tmp_path so that file names in messages are short relative paths."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


def problems_of(path, overrides=(), technique=None) -> list[str]:
    with pytest.raises(Problems) as info:
        load_config(str(path), overrides, technique)
    lines = [str(p) for p in info.value.problems]
    assert lines, "Problems raised without any problem"
    return lines


def test_plain_scene_loads(here):
    cfg, _ = load_config(str(write(here, "scene.toml", SCENE)))
    assert cfg.scene.name == "tiny"
    assert (cfg.camera.width, cfg.camera.height) == (100, 80)
    assert [o.name for o in cfg.objects] == ["ball", "teapot"]
    assert cfg.objects[1].subdivisions == 2
    assert cfg.mirrors[0].reflectance == 0.5


# ---------------------------------------------------------------- includes


def test_include_is_merged_and_including_file_wins(here):
    write(
        here,
        "base.toml",
        """
        [scene]
        name = "base"
        shading = "lambert"
        ambient = 0.3
        [camera]
        eye = [0.0, 1.0, 3.0]
        target = [0.0, 0.5, 0.0]
        width = 100
        height = 80
        [technique]
        name = "raytrace"
        max_depth = 7
        samples = 2
        """
        + MATERIALS,
    )
    main = write(
        here,
        "main.toml",
        """
        include = ["base.toml"]
        [scene]
        name = "main"
        [camera]
        eye = [0.0, 1.0, 3.0]
        target = [0.0, 0.5, 0.0]
        width = 50
        [technique]
        name = "raytrace"
        max_depth = 1
        """
        + OBJECTS,
    )
    cfg, _ = load_config(str(main))
    assert cfg.scene.name == "main"  # including file wins
    assert cfg.scene.shading == "lambert" and cfg.scene.ambient == 0.3  # kept from the include
    assert cfg.camera.width == 50  # including file wins inside a table
    assert cfg.camera.height == 80  # merged key by key
    assert cfg.technique.max_depth == 1
    assert cfg.technique.samples == 2
    assert "red" in cfg.materials  # a section only the include has


def test_later_include_wins_over_earlier(here):
    write(here, "a.toml", '[scene]\nname = "a"\nshading = "lambert"\n')
    write(here, "b.toml", '[scene]\nname = "b"\n')
    main = write(here, "main.toml", 'include = ["a.toml", "b.toml"]\n' + CAMERA)
    cfg, _ = load_config(str(main))
    assert cfg.scene.name == "b"
    assert cfg.scene.shading == "lambert"


def test_include_paths_are_relative_to_the_including_file(here):
    """An included file in another folder: its include path and its mesh paths resolve
    relative to itself."""
    write(here, "presets/mesh/tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    write(
        here,
        "presets/mesh.toml",
        """
        [[objects]]
        name = "tri"
        shape = "mesh"
        path = "mesh/tri.obj"
        material = "red"
        """,
    )
    main = write(
        here,
        "scenes/main.toml",
        'include = ["../presets/mesh.toml"]\n[scene]\nname = "m"\n' + CAMERA + MATERIALS,
    )
    cfg, _ = load_config(str(main))
    (obj,) = cfg.objects
    assert (main.parent / obj.path).resolve() == (here / "presets/mesh/tri.obj").resolve()


def test_error_in_included_file_names_that_file(here):
    write(
        here,
        "base.toml",
        """
        [camera]
        eye = [0.0, 1.0, 3.0]
        target = [0.0, 0.5, 0.0]
        width = -5
        """,
    )
    main = write(here, "main.toml", 'include = ["base.toml"]\n[scene]\nname = "m"\n')
    assert problems_of(main) == ["base.toml: camera.width: must be > 0"]


def test_error_in_including_file_names_it_not_the_include(here):
    write(here, "base.toml", CAMERA)
    main = write(
        here,
        "main.toml",
        'include = ["base.toml"]\n[scene]\nname = "m"\n[camera]\nheight = 0\n',
    )
    assert problems_of(main) == ["main.toml: camera.height: must be > 0"]


def test_syntax_error_in_included_file_names_that_file(here):
    write(here, "base.toml", "[camera\neye = [0, 1, 3]\n")
    main = write(here, "main.toml", 'include = ["base.toml"]\n[scene]\nname = "m"\n')
    (line,) = problems_of(main)
    assert line.startswith("base.toml: TOML syntax error")
    assert "line 1" in line


def test_missing_include_is_reported(here):
    main = write(here, "main.toml", 'include = ["nope.toml"]\n[scene]\nname = "m"\n' + CAMERA)
    (line,) = problems_of(main)
    assert line.startswith("main.toml: include:")
    assert "nope.toml" in line


def test_include_cycle_is_reported(here):
    write(here, "a.toml", 'include = ["b.toml"]\n')
    write(here, "b.toml", 'include = ["a.toml"]\n')
    (line,) = problems_of(here / "a.toml")
    assert "include" in line and "cycle" in line


# ---------------------------------------------------------------- sections in their own files


def test_section_given_as_file_path(here):
    write(here, "parts/cam.toml", CAMERA.replace("width = 100", "width = 33"))
    write(here, "parts/mirrors.toml", MIRRORS + MIRRORS.replace('"floor"', '"floor-2"'))
    main = write(
        here,
        "scene.toml",
        'camera = "parts/cam.toml"\nmirrors = "parts/mirrors.toml"\n[scene]\nname = "s"\n'
        + MATERIALS
        + OBJECTS,
    )
    cfg, _ = load_config(str(main))
    assert cfg.camera.width == 33 and cfg.camera.height == 80
    assert [m.name for m in cfg.mirrors] == ["floor", "floor-2"]


def test_section_file_may_hold_the_section_at_top_level(here):
    write(here, "cam.toml", "eye = [0.0, 1.0, 3.0]\ntarget = [0.0, 0.5, 0.0]\nwidth = 21\n")
    main = write(here, "scene.toml", 'camera = "cam.toml"\n[scene]\nname = "s"\n')
    cfg, _ = load_config(str(main))
    assert cfg.camera.width == 21


def test_errors_name_the_section_file(here):
    write(here, "parts/cam.toml", CAMERA.replace("width = 100", "width = 0"))
    write(
        here,
        "parts/mirrors.toml",
        MIRRORS
        + """
        [[mirrors]]
        name = "ball"
        shape = "sphere"
        center = [0.0, 1.0, 0.0]
        radius = -1.0
        """,
    )
    main = write(
        here,
        "scene.toml",
        'camera = "parts/cam.toml"\nmirrors = "parts/mirrors.toml"\n[scene]\nname = "s"\n',
    )
    assert sorted(problems_of(main)) == [
        "parts/cam.toml: camera.width: must be > 0",
        "parts/mirrors.toml: mirrors.1.radius: must be > 0.0",
    ]


def test_semantic_error_names_the_section_file(here):
    write(
        here,
        "parts/mirrors.toml",
        MIRRORS.replace("[2, 0, 2], [2, 0, -2]", "[-2, 0, 2], [-2, 0, 2]"),
    )
    main = write(
        here, "scene.toml", 'mirrors = "parts/mirrors.toml"\n[scene]\nname = "s"\n' + CAMERA
    )
    (line,) = problems_of(main)
    assert line.startswith("parts/mirrors.toml: mirrors.0.corners:")
    assert "zero area" in line


def test_missing_section_file_names_the_referring_file_and_field(here):
    main = write(here, "scene.toml", 'camera = "nope.toml"\n[scene]\nname = "s"\n')
    (line,) = problems_of(main)
    assert line.startswith("scene.toml: camera:")
    assert "nope.toml" in line


# ---------------------------------------------------------------- --set


def test_set_by_list_index_and_by_item_name(here):
    scene = write(here, "scene.toml", SCENE)
    cfg, _ = load_config(str(scene), ["objects.1.subdivisions=3"])
    assert cfg.objects[1].subdivisions == 3
    cfg, _ = load_config(
        str(scene), ["objects.teapot.subdivisions=4", "mirrors.floor.reflectance=0.25"]
    )
    assert cfg.objects[1].subdivisions == 4
    assert cfg.mirrors[0].reflectance == 0.25
    cfg, _ = load_config(str(scene), ["objects.-1.subdivisions=5"])
    assert cfg.objects[1].subdivisions == 5


def test_set_values_are_parsed_as_toml(here):
    scene = write(here, "scene.toml", SCENE)
    cfg, _ = load_config(
        str(scene),
        [
            "camera.eye=[1, 2.5, 3]",
            "camera.fov_y=40",
            "output.preview=true",
            "scene.name=bare-word",
            'output.dir="quoted dir"',
            "materials.red.color = [0.5, 0.25, 0.125]",
        ],
    )
    assert cfg.camera.eye == (1.0, 2.5, 3.0)
    assert cfg.camera.fov_y == 40.0
    assert cfg.output.preview is True
    assert cfg.scene.name == "bare-word"
    assert cfg.output.dir == "quoted dir"
    assert cfg.materials["red"].color == (0.5, 0.25, 0.125)


def test_set_value_that_parses_as_toml_is_not_kept_as_text(here):
    scene = write(here, "scene.toml", SCENE)
    # `true` is a TOML boolean, so it is no valid scene name; kept as the text "true" it
    # would have passed the name pattern
    (line,) = problems_of(scene, ["scene.name=true"])
    assert line.startswith("--set: scene.name:")


def test_set_creates_missing_tables(here):
    scene = write(here, "scene.toml", SCENE)
    cfg, _ = load_config(str(scene), ["output.log=log.jsonl"])
    assert cfg.output.log == "log.jsonl"


def test_set_errors_name_set_and_the_field(here):
    scene = write(here, "scene.toml", SCENE)
    assert problems_of(scene, ["camera.width=0"]) == ["--set: camera.width: must be > 0"]
    assert problems_of(scene, ["camera.widht=3"]) == [
        "--set: camera.widht: unknown key (did you mean width?)"]
    (line,) = problems_of(scene, ["objects.nosuch.radius=1"])
    assert line.startswith("--set: objects.nosuch.radius:") and "nosuch" in line
    (line,) = problems_of(scene, ["objects.7.radius=1"])
    assert line.startswith("--set: objects.7.radius:")
    (line,) = problems_of(scene, ["camera.width"])
    assert line.startswith("--set:") and "key=value" in line


def test_technique_argument_replaces_scene_technique(here):
    scene = write(here, "scene.toml", SCENE + '[technique]\nname = "raytrace"\nmax_depth = 2\n')
    cfg, _ = load_config(str(scene), technique="raster")
    assert cfg.technique.name == "raster"
    cfg, _ = load_config(str(scene), technique="raytrace")
    assert cfg.technique.max_depth == 2  # same technique: the scene's parameters are kept


def test_no_technique_means_raytrace(here):
    cfg, _ = load_config(str(write(here, "scene.toml", SCENE)))
    assert cfg.technique.name == "raytrace"


def test_set_technique_parameter_on_scene_without_technique(here):
    """The scene names no technique, so it renders with raytrace; a parameter override
    applies to that default instead of failing on the missing `name`."""
    scene = write(here, "scene.toml", SCENE)
    cfg, _ = load_config(str(scene), ["technique.max_depth=2"])
    assert (cfg.technique.name, cfg.technique.max_depth) == ("raytrace", 2)


# ---------------------------------------------------------------- field paths


def test_discriminator_tag_is_not_in_field_path(here):
    scene = write(here, "scene.toml", SCENE.replace("subdivisions = 2", "subdivisions = 0"))
    assert problems_of(scene) == ["scene.toml: objects.1.subdivisions: must be > 0"]


def test_discriminator_tags_dropped_for_every_union(here):
    scene = write(
        here,
        "scene.toml",
        SCENE.replace("color = [0.8, 0.1, 0.1]", "colour = [0.8, 0.1, 0.1]")
        + '[technique]\nname = "raytrace"\nmax_depth = -1\n',
    )
    assert sorted(problems_of(scene)) == [
        "scene.toml: materials.red.colour: unknown key (did you mean color?)",
        "scene.toml: technique.max_depth: must be >= 0",
    ]


def test_item_named_like_a_field_keeps_the_field_in_its_path(here):
    """A mirror named `radius` that lacks its radius: the field is mirrors.1.radius."""
    scene = write(
        here,
        "scene.toml",
        SCENE
        + """
        [[mirrors]]
        name = "radius"
        shape = "sphere"
        center = [0.0, 1.0, 0.0]
        """,
    )
    assert problems_of(scene) == ["scene.toml: mirrors.1.radius: required"]


def test_union_member_labels_are_not_in_field_path(here):
    """`reflectance` is a number or an RGB triple: one line naming the field, not one per
    union member with pydantic's internal labels."""
    scene = write(here, "scene.toml", SCENE.replace("reflectance = 0.5", "reflectance = 2"))
    assert problems_of(scene) == ["scene.toml: mirrors.0.reflectance: must be <= 1.0"]


def test_several_problems_reported_together(here):
    scene = write(
        here,
        "scene.toml",
        SCENE.replace("width = 100", "width = -1").replace("radius = 0.5", "radius = 0"),
    )
    assert sorted(problems_of(scene)) == [
        "scene.toml: camera.width: must be > 0",
        "scene.toml: objects.0.radius: must be > 0.0",
    ]


def test_unknown_material_and_missing_mesh(here):
    text = SCENE.replace('material = "red"\n\n[[objects]]', 'material = "blue"\n\n[[objects]]')
    text += '[[objects]]\nname = "m"\nshape = "mesh"\npath = "missing.obj"\nmaterial = "red"\n'
    lines = problems_of(write(here, "scene.toml", text))
    assert len(lines) == 2
    assert lines[0].startswith("scene.toml: objects.0.material: unknown material 'blue'")
    assert lines[1] == "scene.toml: objects.2.path: file not found: missing.obj"
