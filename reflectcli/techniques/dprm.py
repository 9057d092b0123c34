"""Depth-preserving reflection maps (Bastos & Stuerzlinger): precomputed zexel maps per
planar mirror, forward-warped into the mirror's pixels every frame.

| parameter | type | default | meaning |
|---|---|---|---|
| `maps.count` | int | 1 | maps per mirror, on a hemisphere behind it (1: on its axis) |
| `maps.resolution` | int | 512 | zexels per map side |
| `maps.layout` | "grid", "fibonacci" | "grid" | viewpoint layout (grid needs a square count) |
| `maps.radius` | float | mirror diagonal | viewpoint distance from the mirror's center |
| `maps.spread` | degrees | 45.0 | half-angle of the cap of viewpoints around the axis |
| `maps.per_frame` | int | 1 | maps warped per frame: those nearest the reflected eye |
| `maps.lod` | bool | false | warp the mip level whose density matches the mirror on screen |
| `fill.splat` | 1, 3, 5, "adaptive" | 1 | splat footprint in pixels (adaptive: from the warp) |
| `fill.temporal` | bool | false | keep the previous frame's reflection where no zexel lands |
| `occlusion` | "zbuffer", "ordered" | "zbuffer" | nearest zexel wins, or McMillan's order |
| `reconstruct` | "color", "surface" | "color" | zexel colors, or shade each pixel's own point |

Per frame and visible planar mirror: the eye is reflected across the mirror (equations 1
and 2: M = E - 2 (N.E + d) N; the reflected view direction R_d = E_d - 2 (N.E_d) N, which is
the paper's 2 (N.E_d) N - E_d with E_d pointing toward the eye), the `per_frame` maps whose
viewpoints are nearest M are warped (reflectcli/maps/warp.py), holes are filled as asked, and
the mirror pixels get (1 - r) * base + r * reflected. The warp's cost depends on the zexels,
not on the scene's polygons. Maps are captured at frame 0: objects that move later are not
in them (a warning says so). Pixels no zexel reached are `holes` (an EXR channel) and show
the background. Curved mirrors show (1 - r) * base.

`reconstruct = "surface"` (beyond the paper): maps also keep the triangle each zexel saw,
and a reached pixel intersects its own reflected ray (from M through the pixel center) with
that triangle's plane and shades the point there, as the rasterizer would. Point resampling
of colors puts one-pixel seams along every texture edge (its error floor); this removes
them wherever the zexel's triangle is the surface under the pixel center, or a coplanar
neighbour with the same texture mapping. It costs a shading pass over the mirror's pixels
and stays independent of the polygon count.
"""

from __future__ import annotations

import logging
import math
import time
from typing import Literal

import numpy as np
from pydantic import ConfigDict, Field, model_validator

from ..camera import Camera
from ..config.base import Strict
from ..frame import Frame
from ..geometry import reflection_matrix
from ..maps.cache import MapCache, cache_key
from ..maps.surface import surface_colors
from ..maps.warp import warp_maps
from ..maps.zexel import (
    ZexelMap,
    capture_map,
    map_camera,
    mip_pyramid,
    mirror_frame,
    viewpoints,
)
from ..raster.primary import render_primary
from ..scene.types import PLANAR, Scene
from .base import Technique, precompute_logged, warn_non_planar
from .envmap import scene_extent

log = logging.getLogger("reflect")
MAP_FORMAT = 2  # 2: a T channel with each zexel's triangle


class DprmMaps(Strict):
    count: int = Field(default=1, ge=1, le=4096, description="maps per mirror")
    resolution: int = Field(default=512, ge=8, le=8192, description="zexels per map side")
    layout: Literal["grid", "fibonacci"] = Field(default="grid", description="viewpoints")
    radius: float | None = Field(default=None, gt=0, description="default: mirror diagonal")
    spread: float = Field(default=45.0, gt=0, lt=90, description="cap half-angle, degrees")
    per_frame: int = Field(default=1, ge=1, le=64, description="maps warped per frame")
    lod: bool = Field(default=False, description="warp the mip level matching the mirror")

    @model_validator(mode="after")
    def _count_fits_layout(self) -> DprmMaps:
        if self.layout == "grid" and self.count != math.isqrt(self.count) ** 2:
            raise ValueError(f"count = {self.count} does not fit layout 'grid' (needs a "
                             "square: 1, 4, 9, 16, ...)")
        if self.per_frame > self.count:
            raise ValueError(f"per_frame = {self.per_frame} exceeds count = {self.count}")
        return self


class DprmFill(Strict):
    splat: Literal[1, 3, 5, "adaptive"] = Field(default=1, description="splat footprint")
    temporal: bool = Field(default=False, description="reuse the previous frame in holes")


class DprmParams(Strict):
    model_config = ConfigDict(title="dprm")

    name: Literal["dprm"] = "dprm"
    maps: DprmMaps = Field(default_factory=DprmMaps, description="map capture and choice")
    fill: DprmFill = Field(default_factory=DprmFill, description="exposure filling")
    occlusion: Literal["zbuffer", "ordered"] = Field(default="zbuffer", description="visibility")
    reconstruct: Literal["color", "surface"] = Field(
        default="color", description="zexel colors, or shade each pixel's point of its surface")


class Dprm(Technique):
    name = "dprm"
    Params = DprmParams

    def precompute(self, scene: Scene, on_map=None, on_progress=None) -> list[dict]:
        """Capture (or load) every planar mirror's maps; one record per mirror.
        on_progress(maps done, maps in all) follows the capture map by map."""
        p: DprmMaps = self.params.maps
        total = p.count * int(np.count_nonzero(scene.mirrors.kind == PLANAR))
        done = 0
        cache = MapCache(self.cache_dir)
        near, far = scene_extent(scene)
        n_triangles = scene.geometry(0).all_triangles().count
        records = []
        for k, name in enumerate(scene.mirrors.names):
            if scene.mirrors.kind[k] != PLANAR:
                continue
            mf = mirror_frame(scene, k)
            radius = p.radius if p.radius is not None else mf.diagonal
            points = viewpoints(mf, p.count, p.layout, radius, p.spread)
            cams = [map_camera(mf, v, p.resolution, near, far) for v in points]
            key = cache_key(format=MAP_FORMAT, technique="dprm", scene=scene.content_hash,
                            mirror=name, count=p.count, resolution=p.resolution,
                            layout=p.layout, radius=radius, spread=p.spread, near=near, far=far)
            start = time.perf_counter()
            parts = cache.load("dprm", key, lambda parts: _valid(parts, p, n_triangles))
            status = "cached"
            if parts is None:
                status = "captured"
                maps = []
                for cam in cams:
                    maps.append(capture_map(scene, k, cam))
                    done += 1
                    if on_progress is not None:
                        on_progress(done, total)
                # T: triangle ids, exact in float32 below 2^24
                parts = [(f"map{j:03d}", {"R": m.color[:, :, 0], "G": m.color[:, :, 1],
                                          "B": m.color[:, :, 2], "Z": m.depth,
                                          "T": m.triangle.astype(np.float32)})
                         for j, m in enumerate(maps)]
                cache.store("dprm", key, parts, {
                    "reflect:mirror": name, "reflect:maps": str(p.count),
                    "reflect:near": repr(near), "reflect:far": repr(far)}, [
                    {"reflect:viewpoint": _numbers(cam.eye),
                     "reflect:view_matrix": _numbers(cam.view_matrix()),
                     "reflect:projection_matrix": _numbers(cam.projection_matrix()),
                     "reflect:fov_y": repr(cam.fov_y)} for cam in cams])
            else:
                maps = [ZexelMap(cam, np.stack([c["R"], c["G"], c["B"]], axis=-1), c["Z"],
                                 c["T"].astype(np.int32))
                        for cam, (_, c, _) in zip(cams, parts, strict=True)]
                done += len(maps)
                if on_progress is not None:
                    on_progress(done, total)
            record = {"mirror": name, "index": k, "status": status, "maps": maps,
                      "plane": (mf.normal, float(-mf.normal @ mf.center)),
                      "viewpoints": points, "seconds": time.perf_counter() - start,
                      "path": cache.path("dprm", key)}
            records.append(record)
            if on_map is not None:
                on_map(record)
        return records

    def prepare(self, scene: Scene) -> dict:
        warn_non_planar(scene, "dprm")
        records, seconds = precompute_logged(self, scene, "dprm")
        if scene.frame_count > 1 and scene.geometry(0).key[1]:
            log.warning("dprm: objects move in this scene, but its maps are captured at "
                        "frame 0: reflections show them where they were then")
        return {"scene": scene, "mirrors": records, "previous": {},
                "precompute_seconds": seconds, "triangles": scene.geometry(0).all_triangles()}

    def render(self, state: dict, frame: int, camera: Camera) -> Frame:
        scene: Scene = state["scene"]
        params: DprmParams = self.params
        primary = render_primary(scene, frame, camera)
        result = primary.frame
        self.last_lod_level = 0
        holes = np.zeros(result.surface.shape, bool)
        warp_s = fill_s = 0.0
        used, warped = 0, 0
        for record in state["mirrors"]:
            k = record["index"]
            stencil = result.surface == scene.n_objects + k
            if not stencil.any():
                continue
            t0 = time.perf_counter()
            reflected, reached, n_maps, n_zexels = self._warp(record, camera, stencil, scene,
                                                              state["triangles"])
            t1 = time.perf_counter()
            filled = reached
            if params.fill.temporal:
                prev = state["previous"].get(k)
                if prev is not None:
                    reuse = stencil & ~reached & prev[1]
                    reflected[reuse] = prev[0][reuse]
                    filled = reached | reuse
                state["previous"][k] = (reflected.copy(), filled & stencil)
            hole = stencil & ~filled
            reflected[hole] = scene.background
            result.rgb[stencil] += scene.mirrors.reflectance[k] * reflected[stencil]
            holes |= hole
            fill_s += time.perf_counter() - t1
            warp_s += t1 - t0
            used += n_maps
            warped += n_zexels
        mirror_pixels = int(np.count_nonzero(result.surface >= scene.n_objects))
        result.extra["holes"] = holes.astype(np.float32)
        result.timings.update({"warp": warp_s, "fill": fill_s,
                               "precompute": state["precompute_seconds"] if frame == 0 else 0.0})
        result.stats.update({"maps_used": used, "zexels_warped": warped,
                             "lod_level": getattr(self, "last_lod_level", 0),
                             "holes": int(holes.sum()),
                             "hole_fraction": float(holes.sum() / max(mirror_pixels, 1))})
        return result

    def _lod(self, record: dict, chosen, stencil: np.ndarray):
        """The coarsest mip level that still has a zexel per mirror pixel across the mirror
        (the maps' frustums cover the mirror, so their side spans about its width)."""
        if "pyramids" not in record:
            record["pyramids"] = {}
        pixels_across = math.sqrt(max(int(stencil.sum()), 1))
        level = max(0, int(math.floor(math.log2(
            record["maps"][0].depth.shape[0] / pixels_across))))
        maps = []
        for j in chosen:
            if j not in record["pyramids"]:
                record["pyramids"][j] = mip_pyramid(record["maps"][j])
            pyramid = record["pyramids"][j]
            maps.append(pyramid[min(level, len(pyramid) - 1)])
        return maps, level

    def _warp(self, record: dict, camera: Camera, stencil: np.ndarray,
              scene: Scene | None = None, triangles=None):
        """Reflected colors over the stencil, and which pixels a zexel reached."""
        params: DprmParams = self.params
        k_maps: list[ZexelMap] = record["maps"]
        n, d = record["plane"]
        # equations 1 and 2: the eye mirrored across the plane
        reflect = reflection_matrix(n, d)
        mirrored_eye = camera.eye - 2.0 * (n @ camera.eye + d) * n
        order_by_distance = np.argsort(
            np.linalg.norm(record["viewpoints"] - mirrored_eye, axis=1), kind="stable")
        chosen = order_by_distance[: params.maps.per_frame]
        maps = [k_maps[j] for j in chosen]
        level = 0
        if params.maps.lod:
            maps, level = self._lod(record, chosen, stencil)
        self.last_lod_level = level
        _, best_id, stride, zexels = warp_maps(maps, camera, reflect, mirrored_eye, stencil,
                                               params.fill.splat, params.occlusion == "ordered")
        h, w = stencil.shape
        reflected = np.zeros((h, w, 3), np.float32)
        reached = best_id >= 0
        ids = best_id[reached]
        reflected[reached] = _gather([m.color.reshape(-1, 3) for m in maps], ids, stride)
        if params.reconstruct == "surface" and scene is not None:
            tri = np.full((h, w), -1, np.int32)
            tri[reached] = _gather([m.triangle.reshape(-1) for m in maps], ids, stride)
            shaded, ok = surface_colors(tri, camera, reflect, mirrored_eye, (n, d), triangles,
                                        scene)
            reflected[ok] = shaded[ok]
        return reflected, reached, len(chosen), zexels


def _gather(per_map: list[np.ndarray], ids: np.ndarray, stride: int) -> np.ndarray:
    """Rows of the maps' arrays for warp ids (map slot * stride + zexel index), read map by
    map rather than from a stack of all the maps (a copy of every zexel each frame)."""
    slot, index = np.divmod(ids, stride)
    out = np.empty((ids.size,) + per_map[0].shape[1:], per_map[0].dtype)
    for j, values in enumerate(per_map):
        pick = slot == j
        out[pick] = values[index[pick]]
    return out


def _numbers(values) -> str:
    return " ".join(f"{x:.9g}" for x in np.asarray(values, float).reshape(-1))


def _valid(parts, p: DprmMaps, n_triangles: int | None = None) -> bool:
    """Parts, channels and shapes as captured; triangle ids are -1 or ids of this scene's
    triangles (a map whose key matches but whose ids do not would index out of range)."""
    return len(parts) == p.count and all(
        set(c) >= {"R", "G", "B", "Z", "T"} and c["Z"].shape == (p.resolution, p.resolution)
        and (n_triangles is None or _ids_valid(c["T"], n_triangles))
        for _, c, _ in parts)


def _ids_valid(t: np.ndarray, n_triangles: int) -> bool:
    return bool(np.isfinite(t).all() and (t == np.round(t)).all()
                and (t.size == 0 or (t.min() >= -1 and t.max() < n_triangles)))
