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


def _gltf(folder, uri: str = "m.bin", byte_length: int = 48, count: int = 3,
          indices: bool = False) -> None:
    """A one-triangle .gltf whose buffer is the file `uri` names."""
    import json
    import struct

    (folder / "m.bin").write_bytes(struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0)
                                   + struct.pack("<3I", 0, 1, 99))
    primitive = {"attributes": {"POSITION": 0}, **({"indices": 1} if indices else {})}
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": [{"mesh": 0}], "meshes": [{"primitives": [primitive]}],
           "buffers": [{"uri": uri, "byteLength": byte_length}],
           "bufferViews": [{"buffer": 0, "byteLength": 36},
                           {"buffer": 0, "byteOffset": 36, "byteLength": 12}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": count,
                          "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
                         {"bufferView": 1, "componentType": 5125, "count": 3,
                          "type": "SCALAR"}]}
    (folder / "m.gltf").write_text(json.dumps(doc))


GLTF_OBJECT = '\n[[objects]]\nname = "m"\nshape = "mesh"\npath = "m.gltf"\nmaterial = "red"\n'


def test_gltf_naming_a_buffer_past_the_mesh_limit(tmp_path):
    """A 600-byte .gltf naming a 1.2 GB .bin passed the 512 MiB limit: validate read it all
    (2 GB) before failing. Its size is checked first (a sparse file: nothing is read)."""
    from reflectcli.config.limits import MAX_MESH_BYTES

    _gltf(tmp_path, "big.bin")
    with open(tmp_path / "big.bin", "wb") as f:
        f.truncate(MAX_MESH_BYTES + 1)
    scene = write(tmp_path, "s.toml", TINY + GLTF_OBJECT)
    with chdir(tmp_path):
        check_bad(scene, "s.toml: objects.1.path:", "buffers.0.uri:", "over the limit")


@pytest.mark.parametrize(("uri", "needle"), [
    ("gone.bin", "buffers.0.uri: file not found: gone.bin"),
    ("/etc/hostname", "buffers.0.uri: must be a path relative to the glTF file"),
    ("file:///etc/hostname", "buffers.0.uri: must be a path relative to the glTF file"),
    ("../m.bin", "buffers.0.uri: must stay in the glTF file's folder"),
    ("sub%2F..%2F..%2Fm.bin", "buffers.0.uri: must stay in the glTF file's folder"),
    ("fifo", "buffers.0.uri: not a regular file"),
])
def test_gltf_buffer_uris_that_are_missing_absolute_or_escaping(tmp_path, uri, needle):
    os.mkfifo(tmp_path / "fifo")
    _gltf(tmp_path, uri)
    scene = write(tmp_path, "s.toml", TINY + GLTF_OBJECT)
    with chdir(tmp_path):
        check_bad(scene, "s.toml: objects.1.path:", needle)


@pytest.mark.parametrize(("shape", "needle"), [
    ({"count": 30}, "accessors.0.count: 30 elements need 360 bytes"),
    ({"byte_length": 4800}, "buffers.0.byteLength: 4800 bytes, but its file holds 48"),
    ({"indices": True}, "faces naming vertices it does not have"),
])
def test_malformed_gltf_buffers_are_one_line(tmp_path, shape, needle):
    """A view past its buffer was numpy's "cannot reshape"; an index past the vertices a
    traceback."""
    _gltf(tmp_path, **shape)
    scene = write(tmp_path, "s.toml", TINY + GLTF_OBJECT)
    with chdir(tmp_path):
        check_bad(scene, "s.toml: objects.1.path:", needle)


def test_sound_gltf_with_an_external_buffer_loads(tmp_path):
    from .common import invoke

    _gltf(tmp_path)
    scene = write(tmp_path, "s.toml", TINY + GLTF_OBJECT)
    with chdir(tmp_path):
        result = invoke("validate", scene)
    assert result.exit_code == 0, result.output


def test_obj_material_file_that_is_a_pipe_is_not_read(tmp_path):
    """trimesh's own resolver opened it and waited forever."""
    from .common import invoke

    os.mkfifo(tmp_path / "fifo.mtl")
    (tmp_path / "m.obj").write_text("mtllib fifo.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    scene = write(tmp_path, "s.toml", TINY + GLTF_OBJECT.replace("m.gltf", "m.obj"))
    with chdir(tmp_path):
        result = invoke("validate", scene)
    assert result.exit_code == 0, result.output


def test_glb_naming_an_external_buffer_is_checked_too(tmp_path):
    import struct

    _gltf(tmp_path, "gone.bin")
    text = (tmp_path / "m.gltf").read_bytes()
    text += b" " * (-len(text) % 4)
    (tmp_path / "m.glb").write_bytes(b"glTF" + struct.pack("<II", 2, 20 + len(text))
                                     + struct.pack("<I", len(text)) + b"JSON" + text)
    scene = write(tmp_path, "s.toml", TINY + GLTF_OBJECT.replace("m.gltf", "m.glb"))
    with chdir(tmp_path):
        check_bad(scene, "s.toml: objects.1.path:", "buffers.0.uri: file not found")


def test_a_truncated_png_texture_is_one_line_quoting_libpng(tmp_path, capfd):
    # libpng printed its own "libpng error: ..." line on the process's stderr as well
    import numpy as np
    import OpenImageIO as oiio

    whole = str(tmp_path / "whole.png")
    out = oiio.ImageOutput.create(whole)
    out.open(whole, oiio.ImageSpec(64, 64, 3, oiio.UINT8))
    out.write_image(np.random.default_rng(0).integers(0, 255, (64, 64, 3), dtype=np.uint8))
    out.close()
    data = (tmp_path / "whole.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(data[: len(data) // 2])
    scene = write(tmp_path, "s.toml", TINY.replace(
        'kind = "solid"\ncolor = [0.8, 0.1, 0.1]', 'kind = "texture"\npath = "cut.png"'))
    capfd.readouterr()
    with chdir(tmp_path):
        check_bad(scene, "materials.red.path: cannot read image pixels", "libpng error")
    assert "libpng" not in capfd.readouterr().err


def test_an_integer_of_thousands_of_digits_is_one_line(tmp_path):
    # tomli's int() raised ValueError past Python's 4300-digit limit: a traceback
    from .common import assert_one_line, invoke

    huge = "9" * 5000
    scene = write(tmp_path, "s.toml", TINY.replace("width = 16", f"width = {huge}"))
    with chdir(tmp_path):
        check_bad(scene, "s.toml: a number too long to read", "4300 digits")
        ok = write(tmp_path, "ok.toml", TINY)
        result = invoke("render", ok, "--out", tmp_path / "o", "--set", f"camera.width={huge}")
    assert_one_line(result, "--set: camera.width: must be an integer")
