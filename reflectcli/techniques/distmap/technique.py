"""The distmap technique: layered distance cube maps searched along each reflected ray."""

from __future__ import annotations

import time

import numpy as np

from ...camera import Camera
from ...errors import Problem, Problems
from ...frame import Frame
from ...maps.cache import MapCache, cache_key
from ...maps.cube import FACE_NAMES, face_bases
from ...maps.distance import capture_distance_faces, inverse_depth
from ...maps.distance_search import search_reflections
from ...maps.update import face_capture_frames
from ...raster.primary import render_primary
from ...raster.rasterize import FLAG_MIRROR
from ...scene.types import Scene, scene_extent
from ..base import MapTechnique, precompute_logged
from ..envmap.technique import capture_point
from . import DistmapParams as Params

MAP_FORMAT = 1  # bump when the stored layout changes


class Distmap(MapTechnique):
    name = "distmap"
    Params = Params

    # -- capture -------------------------------------------------------------------------
    def _key(self, scene: Scene, name: str, point, near: float, far: float, frame: int) -> str:
        p: Params = self.params
        return cache_key(format=MAP_FORMAT, technique="distmap", scene=scene.content_hash,
                         mirror=name, point=point, resolution=p.resolution, layers=p.layers,
                         near=near, far=far, capture_frame=frame)

    def _capture_whole(self, scene: Scene, k: int, point, frame: int, cache: MapCache):
        """All six faces at `frame`, through the cache: (color, depth, surface, status)."""
        p: Params = self.params
        name = scene.mirrors.names[k]
        near, far = scene_extent(scene)
        key = self._key(scene, name, point, near, far, frame)
        parts = cache.load("distmap", key, lambda parts: _valid(parts, p))
        if parts is not None:
            shape = (p.layers, 6, p.resolution, p.resolution)
            color = np.empty(shape + (3,), np.float32)
            depth = np.empty(shape, np.float32)
            surface = np.empty(shape, np.int32)
            for i, (_, c, _) in enumerate(parts):
                layer, face = divmod(i, 6)
                color[layer, face] = np.stack([c["R"], c["G"], c["B"]], axis=-1)
                depth[layer, face] = c["Z"]
                surface[layer, face] = c["S"].astype(np.int32)
            return color, depth, surface, "cached"
        color, depth, surface = self._capture(scene, k, point, frame, range(6), None)
        parts = [(f"layer{layer}{FACE_NAMES[face]}",
                  {"R": color[layer, face, :, :, 0], "G": color[layer, face, :, :, 1],
                   "B": color[layer, face, :, :, 2], "Z": depth[layer, face],
                   "S": surface[layer, face].astype(np.float32)})  # ids exact below 2^24
                 for layer in range(p.layers) for face in range(6)]
        cache.store("distmap", key, parts, {
            "reflect:mirror": name, "reflect:layers": str(p.layers),
            "reflect:capture_point": " ".join(f"{v:.9g}" for v in point),
            "reflect:capture_frame": str(frame), "reflect:resolution": str(p.resolution)})
        return color, depth, surface, "captured"

    def _capture(self, scene: Scene, k: int, point, frame: int, faces, out):
        p: Params = self.params
        near, far = scene_extent(scene)
        tris = scene.geometry(frame).all_triangles()
        flags = np.where(tris.surface >= scene.n_objects, FLAG_MIRROR, 0).astype(np.uint8)
        return capture_distance_faces(scene, tris, flags, point, p.resolution, p.layers,
                                      scene.n_objects + k, near, far, faces, out)

    def precompute(self, scene: Scene, on_map=None, on_progress=None,
                   frame: int = 0) -> list[dict]:
        """Capture (or load) every reflector's map as used at frame 0; one record each."""
        p: Params = self.params
        unknown = sorted(set(p.capture) - set(scene.mirrors.names))
        if unknown:
            raise Problems([Problem(scene.source, f"technique.capture.{unknown[0]}",
                                    "no mirror of that name")])
        cache = MapCache(self.cache_dir)
        records = []
        for k, name in enumerate(scene.mirrors.names):
            point = capture_point(scene, k, p)
            start = time.perf_counter()
            color, depth, surface, status = self._capture_whole(scene, k, point, frame, cache)
            near, far = scene_extent(scene)
            record = {"mirror": name, "index": k, "status": status, "point": point,
                      "seconds": time.perf_counter() - start,
                      "path": cache.path("distmap", self._key(scene, name, point, near, far,
                                                              frame)),
                      "color": color, "depth": depth, "surface": surface,
                      "q": inverse_depth(depth), "faces_frame": [frame] * 6}
            records.append(record)
            if on_map is not None:
                on_map(record)
            if on_progress is not None:
                on_progress(k + 1, scene.mirrors.count)
        return records

    # -- render --------------------------------------------------------------------------
    def prepare(self, scene: Scene) -> dict:
        records, seconds = precompute_logged(self, scene, "distmap")
        near, far = scene_extent(scene)
        return {"scene": scene, "maps": records, "precompute_seconds": seconds,
                "near": near, "far": far, "cache": MapCache(self.cache_dir)}

    def _update(self, state: dict, frame: int) -> int:
        """Recapture what the update policy asks for at `frame`; the faces captured."""
        p: Params = self.params
        scene: Scene = state["scene"]
        wanted = face_capture_frames(frame, p.update, p.faces_per_frame)
        captured = 0
        for record in state["maps"]:
            stale = [f for f in range(6) if record["faces_frame"][f] != wanted[f]]
            if not stale:
                continue
            k = record["index"]
            if len(stale) == 6 and len(set(wanted)) == 1:
                color, depth, surface, _ = self._capture_whole(scene, k, record["point"],
                                                               wanted[0], state["cache"])
                record.update(color=color, depth=depth, surface=surface)
            else:
                out = (record["color"].copy(), record["depth"].copy(), record["surface"].copy())
                for at in sorted({wanted[f] for f in stale}):
                    faces = [f for f in stale if wanted[f] == at]
                    out = self._capture(scene, k, record["point"], at, faces, out)
                record.update(color=out[0], depth=out[1], surface=out[2])
            record["q"] = inverse_depth(record["depth"])
            record["faces_frame"] = list(wanted)
            captured += len(stale)
        return captured

    def render(self, state: dict, frame: int, camera: Camera) -> Frame:
        scene: Scene = state["scene"]
        p: Params = self.params
        t0 = time.perf_counter()
        faces = self._update(state, frame)
        t1 = time.perf_counter()
        primary = render_primary(scene, frame, camera)
        result = primary.frame
        h, w = result.surface.shape
        holes = np.zeros((h, w), np.float32)
        taken = np.zeros((h, w), np.int32)
        bases = face_bases()
        a_min = 1e-3 * state["far"]
        t2 = time.perf_counter()
        for record in state["maps"]:
            k = record["index"]
            search_reflections(
                result.rgb, holes, taken, primary.buffers, result.surface, scene.n_objects + k,
                primary.triangles, int(scene.mirrors.kind[k]), scene.mirrors.params[k],
                scene.mirrors.reflectance[k], camera.eye, record["point"], a_min, state["far"],
                record["q"], record["surface"], record["color"], bases, p.steps, p.refine_steps,
                p.filter == "bilinear", scene.background)
        t3 = time.perf_counter()
        mirror = result.surface >= scene.n_objects
        n_mirror = int(mirror.sum())
        result.extra["holes"] = holes
        result.timings.update({"capture": t1 - t0, "search": t3 - t2,
                               "precompute": state["precompute_seconds"] if frame == 0 else 0.0})
        result.stats.update({
            "maps": len(state["maps"]),
            "faces_captured": faces if frame else 6 * len(state["maps"]),
            # raw: rays that crossed nothing, background reflections included (see dprm)
            "unreached": int(holes.sum()),
            "unreached_fraction": float(holes.sum() / max(n_mirror, 1)),
            "search_steps": float(taken[mirror].mean()) if n_mirror else 0.0})
        return result


def _valid(parts, p: Params) -> bool:
    return len(parts) == 6 * p.layers and all(
        set(c) >= {"R", "G", "B", "Z", "S"} and c["Z"].shape == (p.resolution, p.resolution)
        for _, c, _ in parts)
