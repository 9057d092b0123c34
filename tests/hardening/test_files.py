"""Special files, depth limits, NUL bytes: one line naming the file, no hang, no traceback."""

from __future__ import annotations

import os

import pytest

from reflectcli.config.limits import MAX_INCLUDE_DEPTH

from .common import TINY, chdir, check_bad, write


def test_deeply_nested_inline_arrays(tmp_path):
    scene = write(tmp_path, "deep.toml", TINY + "x = " + "[" * 500 + "]" * 500 + "\n")
    with chdir(tmp_path):
        check_bad(scene, "deep.toml", "nested more than")


def test_dotted_key_of_a_thousand_parts(tmp_path):
    scene = write(tmp_path, "dotted.toml", TINY + ".".join(["a"] * 1000) + " = 1\n")
    with chdir(tmp_path):
        check_bad(scene, "dotted.toml", "nested more than")


def test_long_include_chain(tmp_path):
    for i in range(40):
        write(tmp_path, f"c{i}.toml", f'include = ["c{i + 1}.toml"]\n')
    write(tmp_path, "c40.toml", TINY)
    with chdir(tmp_path):
        check_bad(tmp_path / "c0.toml", f"nested more than {MAX_INCLUDE_DEPTH} files deep")


@pytest.mark.parametrize("target", ["/dev/zero", "fifo", "folder"])
def test_include_of_a_special_file(tmp_path, target):
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "folder").mkdir()
    scene = write(tmp_path, "s.toml", f'include = ["{target}"]\n' + TINY)
    with chdir(tmp_path):
        check_bad(scene, "s.toml: include:", target)


@pytest.mark.parametrize("section", ["camera", "fifo", "zero"])
def test_section_file_that_is_special(tmp_path, section):
    os.mkfifo(tmp_path / "fifo")
    target = {"camera": ".", "fifo": "fifo", "zero": "/dev/zero"}[section]
    body = TINY.replace(
        '[camera]\neye = [0.0, 1.0, 3.0]\ntarget = [0.0, 0.5, 0.0]\nwidth = 16\nheight = 12\n', "")
    scene = write(tmp_path, "s.toml", f'camera = "{target}"\n' + body)
    with chdir(tmp_path):
        check_bad(scene, "s.toml: camera:")


def test_nul_byte_in_include(tmp_path):
    scene = write(tmp_path, "s.toml", 'include = ["a\\u0000b"]\n' + TINY)
    with chdir(tmp_path):
        check_bad(scene, "s.toml: include: path contains a NUL byte")


@pytest.mark.parametrize("path", ["fifo", "/dev/zero", "folder", "a\\u0000b"])
def test_mesh_and_texture_paths_that_are_special(tmp_path, path):
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "folder").mkdir()
    mesh = TINY + f'\n[[objects]]\nname = "m"\nshape = "mesh"\npath = "{path}"\nmaterial = "red"\n'
    scene = write(tmp_path, "mesh.toml", mesh)
    with chdir(tmp_path):
        check_bad(scene, "mesh.toml: objects.1.path:")
    tex = TINY.replace('kind = "solid"\ncolor = [0.8, 0.1, 0.1]',
                       f'kind = "texture"\npath = "{path}"')
    scene = write(tmp_path, "tex.toml", tex)
    with chdir(tmp_path):
        check_bad(scene, "tex.toml: materials.red.path:")


def test_scene_file_itself_a_fifo(tmp_path):
    os.mkfifo(tmp_path / "s.toml")
    with chdir(tmp_path):
        check_bad(tmp_path / "s.toml", "not a regular file")
