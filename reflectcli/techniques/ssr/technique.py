"""The screen-space reflection technique class (parameters and method: the package
docstring; kernels in reflectcli/screenspace/)."""

from __future__ import annotations

import time

import numpy as np

from ...camera import Camera
from ...frame import Frame
from ...raster.primary import render_primary
from ...raster.rasterize import RasterWorkspace
from ...scene.types import Scene
from ...screenspace.hiz import build_pyramid, march_hiz_all
from ...screenspace.march import DDA, LINEAR, march_all, outputs
from ...screenspace.rays import mirror_rays
from ...screenspace.resolve import confidence, resolve_hits
from ..base import Technique
from . import SsrParams
from .fallback import BASE, Fallback
from .workspaces import color_copy, screen_state


def march_frame(primary, scene: Scene, camera: Camera, params,
                workspace: RasterWorkspace | None = None) -> dict:
    """Rays of every mirror pixel marched over the primary frame: per-pixel arrays and the
    cells (depth lookups) per ray. Used by the technique and by tests. `workspace`: where
    the ray table (mirror_rays), the march's outputs (march.outputs: every pixel written)
    and the hiz pyramid (build_pyramid: every cell written) are kept across frames; the
    arrays returned are then valid until the next call."""
    frame = primary.frame
    h, w = frame.depth.shape
    t0 = time.perf_counter()
    rays, valid = mirror_rays(primary.buffers, frame.surface, scene.n_objects,
                              primary.triangles, scene.mirrors, camera, params.max_distance,
                              workspace)
    hit, hx, hy, dist, gap, lookups = outputs(h, w, workspace)
    depth = np.ascontiguousarray(frame.depth, np.float32)
    t1 = time.perf_counter()
    pyramid_seconds = 0.0
    if params.march == "hiz":
        flat, table = build_pyramid(depth, workspace)
        pyramid_seconds = time.perf_counter() - t1
        march_hiz_all(rays, valid, flat, table, frame.surface, float(params.thickness),
                      int(params.max_steps), hit, hx, hy, dist, gap, lookups)
    else:
        p = camera.projection_matrix()
        march_all(LINEAR if params.march == "linear" else DDA, rays, valid, depth,
                  frame.surface, float(params.thickness), float(params.stride),
                  float(params.jitter), int(params.max_steps), float(p[0, 0]), float(p[1, 1]),
                  hit, hx, hy, dist, gap, lookups)
    t2 = time.perf_counter()
    n = int(valid.sum())
    return {"rays": rays, "valid": valid, "hit": hit, "hx": hx, "hy": hy, "dist": dist,
            "gap": gap, "lookups": lookups, "ray_count": n,
            "timings": {"rays": t1 - t0, "pyramid": pyramid_seconds,
                        "march": t2 - t1 - pyramid_seconds}}


class Ssr(Technique):
    name = "ssr"
    Params = SsrParams

    def prepare(self, scene: Scene) -> dict:
        fallback = Fallback(self.params.fallback, self.threads, self.cache_dir)
        fallback.prepare(scene)
        return screen_state(scene, fallback)

    def render(self, state: dict, frame_index: int, camera: Camera) -> Frame:
        scene: Scene = state["scene"]
        params = self.params
        primary = render_primary(scene, frame_index, camera, state["primary"])
        result = primary.frame
        marched = march_frame(primary, scene, camera, params, state["screen"])
        t0 = time.perf_counter()
        colors = color_copy(state["screen"], result.rgb)
        tris = primary.triangles
        mats = scene.materials
        resolve_hits(params.resolve == "surface", marched["hit"], marched["hx"], marched["hy"],
                     marched["dist"], marched["rays"], colors, primary.buffers.triangle,
                     result.surface, scene.n_objects, tris.corners, tris.uvs, tris.normals,
                     tris.material, mats.mat_i, mats.mat_f, mats.texels, scene.lights.light_f,
                     scene.shading, scene.ambient, scene.mirrors.reflectance, result.rgb)
        conf = np.zeros(result.depth.shape, np.float32)
        confidence(marched["hit"], marched["hx"], marched["hy"], marched["gap"],
                   marched["rays"], float(params.thickness), conf)
        result.timings.update(marched["timings"])
        result.timings["resolve"] = time.perf_counter() - t0
        source = state["fallback"].apply(scene, primary, camera, marched["hit"], result.rgb,
                                         result.timings)
        hit = marched["hit"]
        result.extra["ssr_hit"] = hit.astype(np.float32)
        result.extra["ssr_distance"] = np.where(hit != 0, marched["dist"], 0.0).astype(
            np.float32, copy=False)
        result.extra["confidence"] = conf
        result.extra["source"] = source
        result.extra["holes"] = (source == BASE).astype(np.float32)  # base only
        mirror_pixels = int(result.mirror_mask.sum())
        result.stats["hole_fraction"] = (float((source == BASE).sum()) / mirror_pixels
                                         if mirror_pixels else 0.0)
        n = marched["ray_count"]
        result.stats["ssr_rays"] = n
        result.stats["cells_per_ray"] = float(marched["lookups"].sum()) / n if n else 0.0
        result.stats["hit_fraction"] = float((hit != 0).sum()) / n if n else 0.0
        return result
