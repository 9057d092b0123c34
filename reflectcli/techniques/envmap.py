"""Environment mapping: a cube or sphere map per reflector, indexed by the reflection vector.

| parameter | type | default | meaning |
|---|---|---|---|
| `map` | "cube", "sphere" | "cube" | cube map, or a sphere (disk) map derived from it |
| `resolution` | int | 256 | texels per cube face side / sphere map side |
| `filter` | "nearest", "bilinear" | "bilinear" | texel filter (clamped at face edges) |
| `parallax` | "none", "box" | "none" | "box": intersect r with a proxy box first |
| `proxy_min`, `proxy_max` | xyz | room bounds | the proxy box (default: `room` objects) |
| `capture_offset` | float | 0.05 | planar mirrors: capture point in front of the center |
| `capture` | {mirror = xyz} | {} | capture point per mirror name (default: the center) |

The classic fast approximation (lecture notes; Bastos & Stuerzlinger sec. 3): the map is
captured once from one point with the reflector itself left out, assuming the environment
is distant; each mirror pixel looks up r = 2 n (n.v) - v. Objects near the reflector show
the known parallax error; `parallax = "box"` removes it for surfaces on the proxy box.
Maps are captured at frame 0 (moving objects are not followed) and cached on disk by a hash
of the scene's content, the capture point and the map parameters (`reflect precompute-maps`).
"""

from __future__ import annotations

import time
from typing import Literal

import numpy as np
from pydantic import ConfigDict, Field

from ..camera import Camera
from ..config.base import Strict, Vec3
from ..errors import Problem, Problems
from ..frame import Frame
from ..maps.cache import MapCache, cache_key
from ..maps.cube import FACE_NAMES, capture_cube, face_bases
from ..maps.lookup import CUBE, SPHERE_MAP, add_reflections
from ..maps.sphere import sphere_from_cube
from ..raster.primary import render_primary
from ..scene.types import CYLINDER, PLANAR, SPHERE, Scene
from .base import Technique, precompute_logged

MAP_FORMAT = 1  # bump when the stored layout changes


class EnvmapParams(Strict):
    model_config = ConfigDict(title="envmap")

    name: Literal["envmap"] = "envmap"
    map: Literal["cube", "sphere"] = Field(default="cube", description="cube or sphere map")
    resolution: int = Field(default=256, ge=4, le=4096, description="texels per face side")
    filter: Literal["nearest", "bilinear"] = Field(default="bilinear", description="filter")
    parallax: Literal["none", "box"] = Field(default="none", description="proxy-box lookup")
    proxy_min: Vec3 | None = Field(default=None, description="proxy box (default: room)")
    proxy_max: Vec3 | None = Field(default=None, description="proxy box (default: room)")
    capture_offset: float = Field(default=0.05, ge=0.0, description="planar capture offset")
    capture: dict[str, Vec3] = Field(default_factory=dict, description="capture points")


def capture_point(scene: Scene, k: int, params: EnvmapParams) -> np.ndarray:
    """Where mirror k's map is captured from (world)."""
    name = scene.mirrors.names[k]
    if name in params.capture:
        return np.array(params.capture[name], float)
    p = scene.mirrors.params[k]
    kind = scene.mirrors.kind[k]
    if kind == PLANAR:
        return p[4:16].reshape(4, 3).mean(axis=0) + params.capture_offset * p[:3]
    if kind == SPHERE:
        return p[:3].copy()
    if kind == CYLINDER:
        return p[:3] + p[3:6] * (p[7] / 2.0)
    tris = scene.geometry(0).mirror_tris
    return tris.corners[tris.surface == scene.n_objects + k].reshape(-1, 3).mean(axis=0)


def scene_extent(scene: Scene) -> tuple[float, float]:
    """(near, far) for captures: from the size of the scene's geometry at frame 0."""
    tris = scene.geometry(0).all_triangles().corners.reshape(-1, 3)
    diag = float(np.linalg.norm(tris.max(axis=0) - tris.min(axis=0))) if len(tris) else 1.0
    return 1e-4 * diag, 4.0 * diag


class Envmap(Technique):
    name = "envmap"
    Params = EnvmapParams

    def precompute(self, scene: Scene, on_map=None, on_progress=None) -> list[dict]:
        """Capture (or load from the cache) every reflector's map; one record per map."""
        params: EnvmapParams = self.params
        unknown = sorted(set(params.capture) - set(scene.mirrors.names))
        if unknown:
            raise Problems([Problem(scene.source, f"technique.capture.{unknown[0]}",
                                    "no mirror of that name")])
        cache = MapCache(self.cache_dir)
        near, far = scene_extent(scene)
        geometry = scene.geometry(0)
        tris = geometry.all_triangles()
        flags = (tris.surface >= scene.n_objects).astype(np.uint8)
        records = []
        for k, name in enumerate(scene.mirrors.names):
            point = capture_point(scene, k, params)
            key = cache_key(format=MAP_FORMAT, technique="envmap", scene=scene.content_hash,
                            mirror=name, point=point, map=params.map,
                            resolution=params.resolution, near=near, far=far)
            expected = 6 if params.map == "cube" else 1
            start = time.perf_counter()
            parts = cache.load("envmap", key, lambda p, n=expected: _valid(p, n, params))
            status = "cached"
            if parts is None:
                status = "captured"
                faces = capture_cube(scene, tris, flags, point, params.resolution,
                                     scene.n_objects + k, near, far)
                if params.map == "cube":
                    images = list(faces)
                    names = list(FACE_NAMES)
                else:
                    images = [sphere_from_cube(faces, params.resolution)]
                    names = ["sphere"]
                parts = [(n, {"R": im[:, :, 0], "G": im[:, :, 1], "B": im[:, :, 2]})
                         for n, im in zip(names, images, strict=True)]
                cache.store("envmap", key, parts, {
                    "reflect:map": params.map, "reflect:mirror": name,
                    "reflect:capture_point": " ".join(f"{v:.9g}" for v in point),
                    "reflect:resolution": str(params.resolution)})
            images = np.stack([np.stack([p[1]["R"], p[1]["G"], p[1]["B"]], axis=-1)
                               for p in parts]).astype(np.float32)
            record = {"mirror": name, "status": status, "seconds": time.perf_counter() - start,
                      "path": cache.path("envmap", key), "point": point, "images": images}
            records.append(record)
            if on_map is not None:
                on_map(record)
            if on_progress is not None:
                on_progress(k + 1, scene.mirrors.count)
        return records

    def prepare(self, scene: Scene) -> dict:
        records, seconds = precompute_logged(self, scene, "envmap")
        params: EnvmapParams = self.params
        if params.proxy_min is not None and params.proxy_max is not None:
            box = np.array([params.proxy_min, params.proxy_max], float)
        elif scene.room_bounds is not None:
            box = scene.room_bounds
        else:
            pts = scene.geometry(0).objects.corners.reshape(-1, 3)
            if len(pts) == 0:  # no objects: the mirrors' bounds (a proxy for nothing)
                pts = scene.geometry(0).all_triangles().corners.reshape(-1, 3)
            box = (np.array([pts.min(axis=0), pts.max(axis=0)], float) if len(pts)
                   else np.array([[-1.0] * 3, [1.0] * 3]))
        return {"scene": scene, "maps": records, "box": box,
                "precompute_seconds": seconds,
                "maps_captured": sum(r["status"] == "captured" for r in records)}

    def render(self, state: dict, frame: int, camera: Camera) -> Frame:
        scene: Scene = state["scene"]
        params: EnvmapParams = self.params
        primary = render_primary(scene, frame, camera)
        result = primary.frame
        t0 = time.perf_counter()
        bases = face_bases()
        map_kind = CUBE if params.map == "cube" else SPHERE_MAP
        dummy = np.zeros((1, 1, 3), np.float32)
        for k, record in enumerate(state["maps"]):
            images = record["images"]
            add_reflections(
                result.rgb, primary.buffers, result.surface, scene.n_objects + k,
                primary.triangles, int(scene.mirrors.kind[k]), scene.mirrors.params[k],
                scene.mirrors.reflectance[k], camera.eye, record["point"], state["box"][0],
                state["box"][1], params.parallax == "box", map_kind,
                images if map_kind == CUBE else np.zeros((6, 1, 1, 3), np.float32),
                images[0] if map_kind == SPHERE_MAP else dummy, bases,
                params.filter == "bilinear")
        result.timings["lookup"] = time.perf_counter() - t0
        result.stats["maps"] = len(state["maps"])
        result.stats["maps_captured"] = state["maps_captured"]
        result.timings["precompute"] = state["precompute_seconds"] if frame == 0 else 0.0
        return result


def _valid(parts, expected: int, params: EnvmapParams) -> bool:
    return len(parts) == expected and all(
        set(p[1]) >= {"R", "G", "B"} and p[1]["R"].shape == (params.resolution,) * 2
        for p in parts)
