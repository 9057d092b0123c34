"""validate agrees with render; bench files and presets validate; did-you-mean; no pydantic
class names; a bad --set is blamed on --set and list items keep the name they were given."""

from __future__ import annotations

from pathlib import Path

import pytest

from .common import TINY, assert_one_line, chdir, check_bad, invoke, write

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("text", ["", "# only\n# comments\n"])
def test_empty_and_comment_only_files_fail_validate_like_render(tmp_path, text):
    scene = write(tmp_path, "s.toml", text)
    with chdir(tmp_path):
        assert_one_line(invoke("validate", scene), "s.toml: empty file")
        result = invoke("render", scene, "--out", tmp_path / "o")
        assert result.exit_code == 2


@pytest.mark.parametrize("path", sorted((ROOT / "configs").glob("*/*.toml")))
def test_bench_files_and_presets_validate(path):
    result = invoke("validate", path)
    assert result.exit_code == 0, result.output
    assert result.stdout == "ok\n"


def test_one_line_for_one_error_in_a_preset(tmp_path):
    preset = write(tmp_path, "p.toml", '[technique]\nname = "raytrace"\nmax_depth = -1\n')
    with chdir(tmp_path):
        assert_one_line(invoke("validate", preset), "p.toml: technique.max_depth: must be >= 0")
        preset = write(tmp_path, "p.toml", '[technique]\nname = "raytrac"\n')
        line = assert_one_line(invoke("validate", preset), "p.toml: technique.name:",
                               "did you mean raytrace?")
    assert "Params" not in line


def test_bench_file_with_a_bad_run_is_one_line(tmp_path):
    bench = write(tmp_path, "b.toml", '[bench]\nname = "b"\n[[runs]]\nscenes = ["s.toml"]\n'
                  'techniques = ["raster"]\n')
    write(tmp_path, "s.toml", TINY.replace("width = 16", "width = -1"))
    with chdir(tmp_path):
        assert_one_line(invoke("validate", bench), "b.toml: runs", "camera.width")


@pytest.mark.parametrize(("override", "expected"), [
    ("camera.fov=30", "--set: camera.fov: unknown key (did you mean fov_y?)"),
    ("objects.ball.radiu=1", "--set: objects.ball.radiu: unknown key (did you mean radius?)"),
    ("objects.ball.radius=-1", "--set: objects.ball.radius: must be > 0.0"),
    # an index from the end was blamed on the scene file under its index from the start
    ("objects.-1.radiu=1", "--set: objects.-1.radiu: unknown key (did you mean radius?)"),
    ("objects.-1.radius=-1", "--set: objects.-1.radius: must be > 0.0"),
    # two in one path: the inner one was named by its index from the start (corners.3)
    ('mirrors.-1.corners.-1="x"', "--set: mirrors.-1.corners.-1: must be an array"),
    ('mirrors.floor.corners.-1="x"', "--set: mirrors.floor.corners.-1: must be an array"),
    ('mirrors.-1.corners.-1.-1="x"', "--set: mirrors.-1.corners.-1.-1: must be a number"),
    # a check across fields was blamed on the file when the field it names was the file's
    ("camera.eye=[0.0, 0.5, 0.0]", "--set: camera.target: must differ from camera.eye"),
    ("camera.eye=[0.0, 5.0, 0.0]", "--set: camera.up: must not be parallel"),
    ("camera.eye.0=1e7", "--set: camera.eye: coordinates must be within +-1e+06"),
    ('objects.ball.shape="sphre"', "--set: objects.ball.shape: unknown shape 'sphre' "
                                   "(did you mean sphere?)"),
    ("camera.eye=[1, 2]", "--set: camera.eye"),
    ("camera=3", "--set: camera: must be a table"),
    ("materials.red.colr=[1, 2, 3]", "--set: materials.red.colr: unknown key "
                                     "(did you mean color?)"),
])
def test_bad_set_is_blamed_on_set(tmp_path, override, expected):
    scene = write(tmp_path, "s.toml", TINY)
    with chdir(tmp_path):
        line = assert_one_line(invoke("render", scene, "--out", tmp_path / "o",
                                      "--set", override), expected)
    assert not (tmp_path / "o").exists()
    assert "Config" not in line and "Params" not in line and "Input should" not in line


@pytest.mark.parametrize("override", ['technique.name="raytrace"',
                                      'technique={name = "envmap"}'])
def test_a_set_technique_name_that_disagrees_with_technique_is_one_line(tmp_path,
                                                                        override):
    # `--technique raster --set technique.name="raytrace"` rendered raytrace, silently
    scene = write(tmp_path, "s.toml", TINY)
    args = ("--technique", "raster", "--set", override)
    with chdir(tmp_path):
        line = assert_one_line(invoke("validate", scene, *args), "--set: technique.name: ",
                               "disagrees with --technique raster")
        assert assert_one_line(invoke("render", scene, "--out", tmp_path / "o", *args)) == line
    assert not (tmp_path / "o").exists()


def test_a_set_technique_that_agrees_with_technique_is_taken(tmp_path):
    # the same name twice is one technique; a --set table without a name is --technique's
    # (it fell back to the default technique, raytrace, which has no `resolution`)
    scene = write(tmp_path, "s.toml", TINY)
    with chdir(tmp_path):
        for args in (("--technique", "raster", "--set", 'technique.name="raster"'),
                     ("--technique", "envmap", "--set", "technique={resolution = 64}")):
            result = invoke("validate", scene, *args)
            assert result.output == "ok\n", result.output


def test_unknown_key_in_an_included_file_names_that_file(tmp_path):
    (tmp_path / "parts").mkdir()
    write(tmp_path, "parts/cam.toml", "[camera]\nfov = 3\n")
    scene = write(tmp_path, "s.toml", 'include = ["parts/cam.toml"]\n' + TINY)
    with chdir(tmp_path):
        check_bad(scene, "parts/cam.toml: camera.fov: unknown key (did you mean fov_y?)")


def test_a_file_without_its_scene_table_is_checked_as_a_fragment(tmp_path):
    """A camera and mirrors but no [scene] is a file render refuses by itself (`scene:
    required`); validate checked it as a scene and failed with the same line, so an include
    fragment holding [camera] and another section failed validate. Now its sections are
    checked, and stderr says render refuses the file by itself, in render's words."""
    text = TINY.split("[camera]")[1].split("[[objects]]")[0] + "[[mirrors]]" + \
        TINY.split("[[mirrors]]")[1]
    scene = write(tmp_path, "s.toml", "[camera]" + text)
    with chdir(tmp_path):
        render = invoke("render", scene, "--out", tmp_path / "o", "--frames", "0")
        result = invoke("validate", scene)
    assert_one_line(render, "s.toml: scene: required")
    assert not (tmp_path / "o").exists()
    assert result.exit_code == 0 and result.stdout == "ok\n"
    assert "(camera, materials, mirrors)" in result.stderr
    assert "cannot be rendered by itself (render refuses it: scene: required)" in result.stderr
    with chdir(tmp_path):  # a fragment's sections are still checked
        write(tmp_path, "s.toml", "[camera]" + text.replace("width = 16", "width = 0"))
        assert_one_line(invoke("validate", scene), "s.toml: camera.width: must be > 0")


def test_a_scene_including_a_camera_and_materials_fragment_validates_as_it_renders(tmp_path):
    """The fragment holds [camera] and [materials]; its object's material is the scene's,
    so checked as a scene by itself it would be wrong on two counts."""
    camera = TINY.split("[camera]")[1].split("[materials.red]")[0]
    write(tmp_path, "frag.toml", "[camera]" + camera + '[[objects]]\nname = "ball"\n'
          'shape = "sphere"\nradius = 0.5\nsegments = 8\nmaterial = "red"\n')
    scene = write(tmp_path, "s.toml", 'include = ["frag.toml"]\n[scene]\nname = "tiny"\n'
                  '[materials.red]\nkind = "solid"\n[[mirrors]]' + TINY.split("[[mirrors]]")[1])
    with chdir(tmp_path):
        assert invoke("validate", scene).output == "ok\n"
        render = invoke("render", scene, "--out", "o", "--frames", "0")
        assert render.exit_code == 0, render.output
        fragment = invoke("validate", tmp_path / "frag.toml")
    assert fragment.exit_code == 0 and fragment.stdout == "ok\n", fragment.output
    assert "section or include file (camera, objects)" in fragment.stderr
    with chdir(tmp_path):  # an error in the fragment names it, in validate as in render
        write(tmp_path, "frag.toml", "[camera]" + camera.replace("width = 16", "width = 0"))
        check_bad(scene, "frag.toml: camera.width: must be > 0")


def test_a_section_file_says_it_cannot_be_rendered_by_itself(tmp_path):
    section = write(tmp_path, "lights.toml", '[[lights]]\nkind = "point"\nposition = [0, 3, 2]\n'
                    '[materials.red]\nkind = "solid"\n')
    with chdir(tmp_path):
        result = invoke("validate", section)
    assert result.exit_code == 0 and result.stdout == "ok\n"
    assert "cannot be rendered by itself" in result.stderr


@pytest.mark.parametrize(("edit", "expected"), [
    # a misspelled kind read the checker as the default solid: its keys were unknown too
    (('[materials.red]\nkind = "solid"\ncolor = [0.8, 0.1, 0.1]\n',
      '[materials.red]\nkindd = "checker"\ncolor0 = [0, 0, 0]\nscale = [4, 4]\n'),
     "s.toml: materials.red.kindd: unknown key (did you mean kind?)"),
    # neither member of the union: not also three lines for the array's missing items
    (("reflectance = 0.5", "reflectance = []"), "s.toml: mirrors.0.reflectance: must be"),
    # pydantic's own words: "String should match pattern '^[A-Za-z0-9._-]+$'"
    (('name = "tiny"', 'name = "my scene"'), "s.toml: scene.name: must be ASCII letters, "
                                             "digits, '.', '_' or '-' (it names a folder)"),
    # a side past 16384 was also a second line, "width x height must be <= 67108864 pixels"
    (("width = 16\nheight = 12", "width = 100000\nheight = 1000"),
     "s.toml: camera.width: must be <= 16384"),
])
def test_one_mistake_is_one_line(tmp_path, edit, expected):
    assert edit[0] in TINY
    text = TINY.replace(*edit)
    with chdir(tmp_path):
        check_bad(write(tmp_path, "s.toml", text), expected)


# union member labels pydantic puts into error locations; none is a key the user wrote
_LABELS = ("constrained-", "tuple[", "literal[", "function-", ".float", ".int", "_kind()")


@pytest.mark.parametrize(("edit", "expected"), [
    # a table where a number or an array goes: one line, no line per union member
    (("reflectance = 0.5", "reflectance = {r = 1}"),
     "s.toml: mirrors.0.reflectance: must be a number or an array"),
    (("translate = [0.0, 0.5, 0.0] }", "translate = [0.0, 0.5, 0.0], scale = {x = 1} }"),
     "s.toml: objects.0.transform.scale: must be a number or an array"),
    (("[[mirrors]]", '[technique]\nname = "envmap"\nupdate = {a = 1}\n\n[[mirrors]]'),
     's.toml: technique.update: must be "once" or "every" or an integer'),
    # the material union's discriminator is a function: name the key the user wrote
    (('kind = "solid"', 'kind = "soild"'),
     "s.toml: materials.red.kind: unknown kind 'soild' (did you mean solid?) "
     "(known: solid, checker, texture)"),
    (('kind = "solid"', "kind = 5"),
     "s.toml: materials.red.kind: unknown kind '5' (known: solid, checker, texture)"),
])
def test_union_errors_name_the_users_field(tmp_path, edit, expected):
    assert edit[0] in TINY
    with chdir(tmp_path):
        line = check_bad(write(tmp_path, "s.toml", TINY.replace(*edit)), expected)
    assert line == expected
    assert not any(label in line for label in _LABELS), line


def test_a_value_one_union_member_refuses_keeps_that_members_line(tmp_path):
    """reflectance = 2 is a number out of range: not "must be <= 1.0 or an array"."""
    with chdir(tmp_path):
        line = check_bad(write(tmp_path, "s.toml",
                               TINY.replace("reflectance = 0.5", "reflectance = 2")),
                         "s.toml: mirrors.0.reflectance: must be <= 1.0")
    assert line == "s.toml: mirrors.0.reflectance: must be <= 1.0"


@pytest.mark.parametrize(("override", "expected"), [
    # the path's keys take the camera's up: a --set up made frame 0 degenerate
    ("camera.up=[0.0, -0.5, -3.0]", "--set: camera.path: up is zero or parallel to the "
                                    "viewing direction at frame 0"),
    ("objects.box.min=[2, 0, 0]", "--set: objects.box.max: must exceed min on every axis"),
])
def test_a_check_across_fields_blames_the_set_that_broke_it(tmp_path, override, expected):
    text = TINY.replace("eye = [0.0, 1.0, 3.0]", "eye = [0.0, 1.0, 4.0]")  # the still camera
    text = text.replace("[materials.red]", "[camera.path]\nframes = 2\nkeys = [{ eye = [0.0, 1.0, "
                        "3.0], target = [0.0, 0.5, 0.0] }, { eye = [0.5, 1.0, 3.0], target = "
                        "[0.0, 0.5, 0.0] }]\n\n[materials.red]")
    text += '\n[[objects]]\nname = "box"\nshape = "box"\nmin = [-1, 0, -1]\nmax = [1, 1, 1]\n' \
            'material = "red"\n'
    scene = write(tmp_path, "s.toml", text)
    with chdir(tmp_path):
        assert invoke("validate", scene).output == "ok\n"
        assert_one_line(invoke("render", scene, "--out", tmp_path / "o", "--set", override),
                        expected)
    assert not (tmp_path / "o").exists()


def test_far_near_ratio_is_blamed_on_the_set_near(tmp_path):
    # far from the file, near from --set: the ratio is the --set's doing
    scene = write(tmp_path, "s.toml", TINY.replace("height = 12", "height = 12\nfar = 10000.0"))
    with chdir(tmp_path):
        assert_one_line(invoke("validate", scene, "--set", "camera.near=1e-6"),
                        "--set: camera.far: far / near must be <= 1e+09")
