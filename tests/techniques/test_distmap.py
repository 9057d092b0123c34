"""distmap against box-projected envmap and the ray tracer: exact in a room of planar faces,
better than envmap where objects stand free, and holes falling as layers grow."""

from __future__ import annotations

import numpy as np
import OpenImageIO as oiio
from conftest import SCENES, psnr, render_frame


def _smooth_texture(path, h=64, w=64):
    """A smooth colour gradient (texture resampling then costs no dB at edges)."""
    u = np.linspace(0, 1, w)[None, :, None]
    v = np.linspace(0, 1, h)[:, None, None]
    img = np.concatenate([0.2 + 0.6 * v + 0 * u, 0.3 + 0.5 * np.sin(np.pi * u) + 0 * v,
                          0.9 - 0.4 * v * u], axis=2)
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(w, h, 3, oiio.FLOAT))
    out.write_image(np.ascontiguousarray(img, np.float32))
    out.close()


def box_room(tmp_path, mirror: str = "planar"):
    """A box room of planar faces, no free-standing objects, a wall mirror or a ball."""
    _smooth_texture(tmp_path / "grad.exr")
    mirror_toml = ("""shape = "quad"
corners = [[-3.0, 0.8, -3.99], [2.0, 0.8, -3.99], [2.0, 3.4, -3.99], [-3.0, 3.4, -3.99]]"""
                   if mirror == "planar" else """shape = "sphere"
center = [0.5, 1.5, 0.0]
radius = 1.0
segments = 96""")
    target = "[-0.5, 2.0, -4.0]" if mirror == "planar" else "[0.0, 1.8, 0.0]"
    (tmp_path / "box.toml").write_text(f"""
[scene]
name = "box-room"
[camera]
eye = [3.0, 2.5, 3.5]
target = {target}
fov_y = 40.0
width = 160
height = 160
[materials.grad]
kind = "texture"
path = "grad.exr"
srgb = false
[[objects]]
name = "room"
shape = "room"
min = [-5.0, 0.0, -4.0]
max = [5.0, 4.0, 6.0]
material = "grad"
[[mirrors]]
name = "mirror"
{mirror_toml}
[technique]
name = "distmap"
""")
    return tmp_path / "box.toml"


def mirror_psnr(out, ref):
    both = out.mirror_mask & ref.mirror_mask
    return psnr(out.rgb[both], ref.rgb[both])


def test_box_room_equals_box_projection_and_raytrace(tmp_path):
    scene = box_room(tmp_path)
    ref, _ = render_frame(scene, "raytrace", 0, ("technique.max_depth=1",))
    boxed, _ = render_frame(scene, "envmap", 0, ('technique.parallax="box"',))
    dist, _ = render_frame(scene, "distmap", 0)
    assert dist.mirror_mask.sum() > 5000
    assert mirror_psnr(dist, boxed) >= 40.0
    assert mirror_psnr(dist, ref) >= 35.0
    assert mirror_psnr(boxed, ref) >= 35.0
    assert dist.stats["hole_fraction"] < 1e-3


def test_box_room_ball_equals_box_projection(tmp_path):
    """A ball: the tessellated sphere costs both the same against the exact ray tracer."""
    scene = box_room(tmp_path, "sphere")
    ref, _ = render_frame(scene, "raytrace", 0, ("technique.max_depth=1",))
    boxed, _ = render_frame(scene, "envmap", 0, ('technique.parallax="box"',))
    dist, _ = render_frame(scene, "distmap", 0)
    assert mirror_psnr(dist, boxed) >= 40.0
    assert abs(mirror_psnr(dist, ref) - mirror_psnr(boxed, ref)) < 0.5
