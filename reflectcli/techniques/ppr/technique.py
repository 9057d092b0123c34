"""The pixel-projected reflection technique class (parameters and method: the package
docstring; kernels in reflectcli/screenspace/project.py)."""

from __future__ import annotations

import time

import numpy as np

from ...camera import Camera
from ...frame import Frame
from ...raster.primary import render_primary
from ...raster.rasterize import RasterWorkspace
from ...raster.rasterize.buffers import scratch
from ...scene.types import PLANAR, Scene
from ...screenspace.march import outputs
from ...screenspace.project import EMPTY, decode, fill_holes, project_sources, scatter_min
from ...screenspace.rays import mirror_rays
from ...screenspace.resolve import resolve_hits
from ..base import Technique, warn_non_planar
from ..ssr.fallback import BASE, Fallback
from ..ssr.workspaces import color_copy, screen_state
from . import PprParams


def project_frame(primary, scene: Scene, camera: Camera, fill: bool,
                  workspace: RasterWorkspace | None = None) -> dict:
    """The projection and reflection passes over the primary frame: per-pixel arrays.
    `workspace`: where the ray table (mirror_rays), the decoded outputs (march.outputs:
    decode writes every pixel) and the scatter's arrays are kept across frames; the arrays
    returned are then valid until the next call. What an earlier frame left in them is
    never read: the key buffer is set to EMPTY here, project_sources writes every source's
    target and key, fill_holes every pixel of its `out` and `filled` (`filled` is cleared
    here without a fill)."""
    frame = primary.frame
    h, w = frame.depth.shape
    t0 = time.perf_counter()
    buf = primary.buffers
    tris = primary.triangles
    clip_from_world = camera.projection_matrix() @ camera.view_matrix()
    buffer = scratch(workspace, "ppr_keys_min", (h * w,), np.uint64)
    buffer.fill(EMPTY)  # scatter_min's targets and decode read it: EMPTY where no key lands
    targets = scratch(workspace, "ppr_targets", (h * w,), np.int32)
    keys = scratch(workspace, "ppr_keys", (h * w,), np.uint64)
    mirrors = scene.mirrors
    eye = np.asarray(camera.eye, np.float64)
    projected = 0
    for k in range(mirrors.count):
        sid = scene.n_objects + k
        if mirrors.kind[k] != PLANAR or not (frame.surface == sid).any():
            continue
        n, d = mirrors.plane(k)
        plane = np.append(np.asarray(n, np.float64), float(d))
        if plane[:3] @ eye + plane[3] < 0:  # face the plane toward the eye
            plane = -plane
        project_sources(buf.triangle, buf.b1, buf.b2, frame.surface, scene.n_objects,
                        tris.corners, plane, sid, clip_from_world, targets, keys)
        scatter_min(targets, keys, buffer)
        projected += int((targets >= 0).sum())
    t1 = time.perf_counter()
    filled = scratch(workspace, "ppr_filled", (h, w), np.bool_)
    if fill:
        out = scratch(workspace, "ppr_keys_filled", (h * w,), np.uint64)
        fill_holes(buffer, frame.surface, scene.n_objects, w, out, filled)
        buffer = out
    else:
        filled.fill(False)  # (read for the `filled` count)
    rays, _ = mirror_rays(buf, frame.surface, scene.n_objects, tris, mirrors, camera,
                          camera.far, workspace)
    hit, hx, hy, dist, _, _ = outputs(h, w, workspace)
    decode(buffer, w, rays, buf.triangle, buf.b1, buf.b2, tris.corners, hit, hx, hy, dist)
    t2 = time.perf_counter()
    return {"rays": rays, "hit": hit, "hx": hx, "hy": hy, "dist": dist, "filled": filled,
            "projected": projected,
            "timings": {"project": t1 - t0, "reflect": t2 - t1}}


class Ppr(Technique):
    name = "ppr"
    Params = PprParams

    def prepare(self, scene: Scene) -> dict:
        warn_non_planar(scene, "ppr")
        fallback = Fallback(self.params.fallback, self.threads, self.cache_dir)
        fallback.prepare(scene)
        return screen_state(scene, fallback)

    def render(self, state: dict, frame_index: int, camera: Camera) -> Frame:
        scene: Scene = state["scene"]
        params = self.params
        primary = render_primary(scene, frame_index, camera, state["primary"])
        result = primary.frame
        p = project_frame(primary, scene, camera, params.fill, state["screen"])
        t0 = time.perf_counter()
        colors = color_copy(state["screen"], result.rgb)
        tris = primary.triangles
        mats = scene.materials
        resolve_hits(params.resolve == "surface", p["hit"], p["hx"], p["hy"], p["dist"],
                     p["rays"], colors, primary.buffers.triangle, result.surface,
                     scene.n_objects, tris.corners, tris.uvs, tris.normals, tris.material,
                     mats.mat_i, mats.mat_f, mats.texels, scene.lights.light_f, scene.shading,
                     scene.ambient, scene.mirrors.reflectance, result.rgb)
        result.timings.update(p["timings"])
        result.timings["resolve"] = time.perf_counter() - t0
        hit = p["hit"]
        source = state["fallback"].apply(scene, primary, camera, hit, result.rgb,
                                         result.timings)
        result.extra["ppr_hit"] = hit.astype(np.float32)
        result.extra["ppr_distance"] = np.where(hit != 0, p["dist"], 0.0).astype(
            np.float32, copy=False)
        result.extra["source"] = source
        result.extra["holes"] = (source == BASE).astype(np.float32)  # base only
        mirror_pixels = int(result.mirror_mask.sum())
        result.stats["hole_fraction"] = (float((source == BASE).sum()) / mirror_pixels
                                         if mirror_pixels else 0.0)
        mirror = int(result.mirror_mask.sum())
        result.stats["projected"] = p["projected"]
        result.stats["filled"] = int(p["filled"].sum())
        result.stats["hit_fraction"] = float((hit != 0).sum()) / mirror if mirror else 0.0
        return result
