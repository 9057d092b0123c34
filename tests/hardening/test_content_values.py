"""Values inside a user's mesh and texture files: past the limits a scene's own numbers have,
they are one line naming the field from validate and render alike, not a frame refused for
NaN pixels after `validate` said ok."""

from __future__ import annotations

import numpy as np
import pytest

from .common import TINY, chdir, check_bad, write

TEXTURED = TINY.replace('kind = "solid"\ncolor = [0.8, 0.1, 0.1]',
                        'kind = "texture"\npath = "t.exr"\nsrgb = false')


def _texture(path, value: float) -> None:
    import OpenImageIO as oiio

    pixels = np.full((4, 4, 3), 0.5, np.float32)
    pixels[1, 1, 0] = value
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(4, 4, 3, oiio.FLOAT))
    out.write_image(pixels)
    out.close()


@pytest.mark.parametrize("uv", ["nan inf", "1e300 -1e300", "2e9 0"])
def test_mesh_texture_coordinates_past_the_limit(tmp_path, uv):
    # NaN pixels under a texture: "frame 0: channel R has 32 non-finite value(s)" at render
    # time, after validate had said ok (1e300 also printed numpy's overflow warning)
    write(tmp_path, "m.obj", f"v -1 0 0\nv 1 0 0\nv 0 2 0\nvt {uv}\nf 1/1 2/1 3/1\n")
    _texture(tmp_path / "t.exr", 0.5)
    scene = write(tmp_path, "s.toml", TEXTURED + '\n[[objects]]\nname = "m"\nshape = "mesh"\n'
                  'path = "m.obj"\nmaterial = "red"\n')
    with chdir(tmp_path):
        check_bad(scene, "s.toml: objects.1.path:", "texture coordinates that are not finite "
                  "or past +-1e+09")


def test_texture_texels_past_the_limit(tmp_path):
    # 1e38 is a finite float32, but lit by a light it overflowed to NaN pixels at render time
    _texture(tmp_path / "t.exr", 1e38)
    lit = TEXTURED.replace('name = "tiny"', 'name = "tiny"\nshading = "lambert"')
    scene = write(tmp_path, "s.toml", lit + '\n[[lights]]\nkind = "directional"\n'
                  'direction = [0, -1, -1]\nintensity = 1000\n')
    with chdir(tmp_path):
        check_bad(scene, "s.toml: materials.red.path: texture has texels past +-1e+09")


def test_texture_texels_within_the_limit_load(tmp_path):
    from reflectcli.scene.textures import load_texture

    _texture(tmp_path / "t.exr", -5.0)  # a negative texel, as a negative color, is allowed
    assert load_texture(str(tmp_path / "t.exr"), srgb=False).min() == -5.0


def test_a_negative_clutter_seed_names_the_seed(tmp_path):
    # numpy's "expected non-negative integer" was blamed on objects.1.shape
    scene = write(tmp_path, "s.toml", TINY + '\n[[objects]]\nname = "c"\nshape = "clutter"\n'
                  'min = [-1, 0, -1]\nmax = [1, 1, 1]\ntriangles = 500\nseed = -1\n'
                  'material = "red"\n')
    with chdir(tmp_path):
        check_bad(scene, "s.toml: objects.1.seed: must be >= 0")
