"""The distmap technique: layered distance cube maps searched along each reflected ray."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ...camera import Camera
from ...errors import Problem, Problems
from ...frame import Frame
from ...maps.cache import MapCache, MapShape, cache_key
from ...maps.cube import FACE_NAMES, face_bases
from ...maps.distance import capture_distance_faces, inverse_depth
from ...maps.distance_search import search_reflections, search_texels
from ...maps.update import face_capture_frames
from ...raster.primary import render_primary
from ...raster.rasterize import FLAG_MIRROR, RasterWorkspace
from ...raster.rasterize.buffers import scratch
from ...scene.types import Scene, scene_extent
from ..base import MapRecord, MapTechnique, precompute_logged, warn_stale
from ..envmap.technique import capture_point
from . import DistmapParams as Params

MAP_FORMAT = 1  # bump when the stored layout changes


@dataclass
class DistmapRecord(MapRecord):
    """One reflector's layered distance cube map and the frame each face was captured at."""

    index: int  # the mirror's index k
    point: np.ndarray  # (3,) capture point, world
    color: np.ndarray  # (layers, 6, S, S, 3) float32, linear RGB
    depth: np.ndarray  # (layers, 6, S, S) float32, eye depth along the face's axis
    surface: np.ndarray  # (layers, 6, S, S) int32 surface ids (-1: none)
    q: np.ndarray  # (6, S, S, layers) inverse depth of `depth`, what the search interpolates
    ids: np.ndarray  # (6, S, S, layers) `surface` as the search reads it (search_texels)
    faces_frame: list[int]  # per cube face, the frame_index its capture comes from


@dataclass
class DistmapState:
    scene: Scene
    maps: list[DistmapRecord]
    precompute_seconds: float
    near: float
    far: float
    cache: MapCache
    # the primary pass's scratch, triangle ids and barycentrics (read only while the frame
    # renders) and the search's step counts, kept across frames
    primary: RasterWorkspace = field(default_factory=lambda: RasterWorkspace(ids=True))


class Distmap(MapTechnique):
    name = "distmap"
    Params = Params

    # -- capture -------------------------------------------------------------------------
    def _key(self, scene: Scene, name: str, point, near: float, far: float,
             frame_index: int) -> str:
        p: Params = self.params
        return cache_key(format=MAP_FORMAT, technique="distmap", scene=scene.content_hash,
                         mirror=name, point=point, resolution=p.resolution, layers=p.layers,
                         near=near, far=far, capture_frame=frame_index)

    def _capture_whole(self, scene: Scene, k: int, point, frame_index: int, cache: MapCache):
        """All six faces at `frame_index`, through the cache: (color, depth, surface,
        status)."""
        p: Params = self.params
        name = scene.mirrors.names[k]
        near, far = scene_extent(scene)
        key = self._key(scene, name, point, near, far, frame_index)
        parts = cache.load("distmap", key, MapShape(6 * p.layers, p.resolution, 5),
                           lambda parts: _valid(parts, p))
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
        color, depth, surface = self._capture(scene, k, point, frame_index, range(6), None)
        parts = [(f"layer{layer}{FACE_NAMES[face]}",
                  {"R": color[layer, face, :, :, 0], "G": color[layer, face, :, :, 1],
                   "B": color[layer, face, :, :, 2], "Z": depth[layer, face],
                   "S": surface[layer, face].astype(np.float32)})  # ids exact below 2^24
                 for layer in range(p.layers) for face in range(6)]
        cache.store("distmap", key, parts, {
            "reflect:mirror": name, "reflect:layers": str(p.layers),
            "reflect:capture_point": " ".join(f"{v:.9g}" for v in point),
            "reflect:capture_frame": str(frame_index), "reflect:resolution": str(p.resolution)})
        return color, depth, surface, "captured"

    def _capture(self, scene: Scene, k: int, point, frame_index: int, faces, out):
        """The given faces of mirror k's map from the geometry of `frame_index`, into `out`
        (color, depth, surface) or new arrays."""
        p: Params = self.params
        near, far = scene_extent(scene)
        tris = scene.geometry(frame_index).all_triangles()
        flags = np.where(tris.surface >= scene.n_objects, FLAG_MIRROR, 0).astype(np.uint8)
        return capture_distance_faces(scene, tris, flags, point, p.resolution, p.layers,
                                      scene.n_objects + k, near, far, faces, out)

    def precompute(self, scene: Scene, on_map=None, on_progress=None,
                   frame_index: int = 0) -> list[DistmapRecord]:
        """Capture (or load) every reflector's map as used at `frame_index`; one record
        each."""
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
            wanted = face_capture_frames(frame_index, p.update, p.faces_per_frame)
            at = wanted[0] if len(set(wanted)) == 1 else frame_index
            color, depth, surface, status = self._capture_whole(scene, k, point, at, cache)
            faces_frame = [at] * 6
            stale = [f for f in range(6) if wanted[f] != at]
            for then in sorted({wanted[f] for f in stale}):
                color, depth, surface = self._capture(
                    scene, k, point, then, [f for f in stale if wanted[f] == then],
                    (color, depth, surface))
                for f in stale:
                    if wanted[f] == then:
                        faces_frame[f] = then
            near, far = scene_extent(scene)
            record = DistmapRecord(
                name, status, time.perf_counter() - start,
                cache.path("distmap", self._key(scene, name, point, near, far, at)),
                k, point, color, depth, surface, *search_texels(inverse_depth(depth), surface),
                faces_frame)
            records.append(record)
            if on_map is not None:
                on_map(record)
            if on_progress is not None:
                on_progress(k + 1, scene.mirrors.count)
        return records

    # -- render --------------------------------------------------------------------------
    def prepare(self, scene: Scene) -> DistmapState:
        records, seconds = precompute_logged(self, scene, "distmap")
        near, far = scene_extent(scene)
        warn_stale(scene, "distmap", self.params.update)
        return DistmapState(scene, records, seconds, near, far, MapCache(self.cache_dir))

    def _update(self, state: DistmapState, frame_index: int) -> int:
        """Recapture what the update policy asks for at `frame_index`; the faces captured."""
        p: Params = self.params
        scene = state.scene
        wanted = face_capture_frames(frame_index, p.update, p.faces_per_frame)
        captured = 0
        for record in state.maps:
            stale = [f for f in range(6) if record.faces_frame[f] != wanted[f]]
            if not stale:
                continue
            k = record.index
            if len(stale) == 6 and len(set(wanted)) == 1:
                record.color, record.depth, record.surface, _ = self._capture_whole(
                    scene, k, record.point, wanted[0], state.cache)
            else:
                out = (record.color.copy(), record.depth.copy(), record.surface.copy())
                for at in sorted({wanted[f] for f in stale}):
                    faces = [f for f in stale if wanted[f] == at]
                    out = self._capture(scene, k, record.point, at, faces, out)
                record.color, record.depth, record.surface = out
            record.q, record.ids = search_texels(inverse_depth(record.depth), record.surface)
            record.faces_frame = list(wanted)
            captured += len(stale)
        return captured

    def render(self, state: DistmapState, frame_index: int, camera: Camera) -> Frame:
        scene = state.scene
        p: Params = self.params
        t0 = time.perf_counter()
        faces = self._update(state, frame_index)
        t1 = time.perf_counter()
        primary = render_primary(scene, frame_index, camera, state.primary)
        result = primary.frame
        h, w = result.surface.shape
        holes = np.zeros((h, w), np.float32)  # a channel of the frame: its own
        taken = scratch(state.primary, "steps_taken", (h, w), np.int32)
        taken.fill(0)  # (kept: written only on the pixels of mirrors with maps)
        bases = face_bases()
        a_min = 1e-3 * state.far
        t2 = time.perf_counter()
        for record in state.maps:
            k = record.index
            search_reflections(
                result.rgb, holes, taken, primary.buffers, result.surface, scene.n_objects + k,
                primary.triangles, int(scene.mirrors.kind[k]), scene.mirrors.params[k],
                scene.mirrors.reflectance[k], camera.eye, record.point, a_min, state.far,
                record.q, record.ids, record.color, bases, p.steps, p.refine_steps,
                p.filter == "bilinear", scene.background)
        t3 = time.perf_counter()
        mirror = result.mirror_mask  # surface >= n_objects
        n_mirror = int(mirror.sum())
        result.extra["holes"] = holes
        result.timings.update({"capture": t1 - t0, "search": t3 - t2})
        result.stats.update({
            # one-time capture, done in prepare (never in a frame's time)
            "precompute_seconds": state.precompute_seconds,
            "maps": len(state.maps),
            "faces_captured": faces if frame_index else 6 * len(state.maps),
            # raw: rays that crossed nothing, background reflections included (see dprm)
            "unreached": int(holes.sum()),
            "unreached_fraction": float(holes.sum() / max(n_mirror, 1)),
            "search_steps": float(taken[mirror].mean()) if n_mirror else 0.0})
        return result


def _valid(parts, p: Params) -> bool:
    return len(parts) == 6 * p.layers and all(
        set(c) >= {"R", "G", "B", "Z", "S"} and c["Z"].shape == (p.resolution, p.resolution)
        for _, c, _ in parts)
