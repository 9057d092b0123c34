"""Shared helpers of the ssr and ppr tests: a frame's primary pass and the ground truth."""

from __future__ import annotations

from pathlib import Path

from conftest import open_scene
from naive_screenspace import truth_hits

from reflectcli.raster.primary import render_primary
from reflectcli.screenspace.rays import mirror_rays

# a planar mirror whose whole reflection is on screen and unoccluded: a floor mirror, a
# checkered wall behind it and two boxes standing on the floor, seen from above; every
# reflected ray that lands on something lands on a face the camera sees
CLEAN = """
[scene]
name = "clean"
shading = "lambert"
ambient = 0.2
[camera]
eye = [0.0, 2.2, 3.0]
target = [0.0, 0.4, -1.0]
fov_y = 60.0
width = 160
height = 120
near = 0.05
far = 50.0
[[lights]]
kind = "directional"
direction = [-0.3, -1.0, -0.5]
intensity = 0.8
[materials.wall]
kind = "checker"
color0 = [0.15, 0.2, 0.3]
color1 = [0.8, 0.8, 0.85]
scale = [21, 12]
[materials.box]
kind = "checker"
color0 = [0.9, 0.4, 0.1]
color1 = [0.2, 0.1, 0.6]
scale = [2, 2]
[[objects]]
name = "wall"
shape = "quad"
corners = [[-8, 0, -2], [8, 0, -2], [8, 4, -2], [-8, 4, -2]]
material = "wall"
[[objects]]
name = "box-a"
shape = "box"
min = [-1.2, 0.0, -1.0]
max = [-0.6, 0.5, -0.6]
material = "box"
[[objects]]
name = "box-b"
shape = "box"
min = [0.5, 0.0, -0.4]
max = [1.0, 0.35, 0.1]
material = "box"
[[mirrors]]
name = "floor"
shape = "quad"
corners = [[-3, 0, 2], [3, 0, 2], [3, 0, -2], [-3, 0, -2]]
reflectance = 0.8
base = [0.1, 0.1, 0.1]
"""


def clean_scene(tmp_path: Path) -> Path:
    path = tmp_path / "clean.toml"
    path.write_text(CLEAN)
    return path


def primary_of(scene: str | Path, frame: int = 0, overrides=(), technique="ssr"):
    """(primary pass, built scene, camera) of a scene file or bundled scene name."""
    opened = open_scene(scene, technique, overrides)
    built = opened.scene
    camera = opened.camera(frame)
    return render_primary(built, frame, camera), built, camera


def truth(primary, built, camera, frame=0):
    """(visible, landed): the ray tracer's reflected rays against the primary frame."""
    rays, valid = mirror_rays(primary.buffers, primary.frame.surface, built.n_objects,
                              primary.triangles, built.mirrors, camera, camera.far)
    return truth_hits(rays, valid, built.geometry(frame), primary.frame.depth,
                      primary.frame.surface, camera)


def precision_recall(hit, visible):
    tp = float((hit & visible).sum())
    return tp / max(int(hit.sum()), 1), tp / max(int(visible.sum()), 1)
