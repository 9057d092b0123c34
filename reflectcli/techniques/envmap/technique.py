"""The environment-mapping technique class (parameters and method: the package docstring)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ...camera import Camera
from ...errors import Problem, Problems
from ...frame import Frame
from ...maps.cache import MapCache, MapShape, cache_key
from ...maps.cube import FACE_NAMES, capture_cube, face_bases
from ...maps.lookup import CUBE, SPHERE_MAP, add_reflections
from ...maps.sphere import sphere_from_cube
from ...maps.update import face_capture_frames, map_capture_frame
from ...raster.primary import render_primary
from ...raster.rasterize import FLAG_MIRROR, RasterWorkspace
from ...scene.types import CYLINDER, PLANAR, SPHERE, Scene, scene_extent
from ..base import MapRecord, MapTechnique, precompute_logged, warn_stale
from . import EnvmapParams

MAP_FORMAT = 1  # bump when the stored layout changes


@dataclass
class EnvmapRecord(MapRecord):
    """One reflector's map: where it was captured and its images (6 cube faces or 1 disk)."""

    point: np.ndarray  # (3,) capture point, world
    images: np.ndarray  # (6 or 1, S, S, 3) float32, linear RGB
    # per cube face (one entry for a sphere map), the frame_index its capture comes from
    faces_frame: list[int] = field(default_factory=lambda: [0] * 6)


@dataclass
class EnvmapState:
    scene: Scene
    maps: list[EnvmapRecord]
    box: np.ndarray  # (2, 3) parallax proxy box, world
    precompute_seconds: float
    maps_captured: int
    cache: MapCache | None = None
    # the primary pass's scratch, triangle ids and barycentrics (read only while the frame
    # renders), kept across frames
    primary: RasterWorkspace = field(default_factory=lambda: RasterWorkspace(ids=True))


def capture_point(scene: Scene, k: int, params: EnvmapParams) -> np.ndarray:
    """Where mirror k's map is captured from (world)."""
    mirrors = scene.mirrors
    name = mirrors.names[k]
    if name in params.capture:
        return np.array(params.capture[name], float)
    kind = mirrors.kind[k]
    if kind == PLANAR:
        n, _ = mirrors.plane(k)
        return mirrors.corners(k).mean(axis=0) + params.capture_offset * n
    if kind == SPHERE:
        center, _ = mirrors.sphere(k)
        return center.copy()
    if kind == CYLINDER:
        origin, axis, _, height = mirrors.cylinder(k)
        return origin + axis * (height / 2.0)
    tris = scene.geometry(0).mirror_tris
    return tris.corners[tris.surface == scene.n_objects + k].reshape(-1, 3).mean(axis=0)


class Envmap(MapTechnique):
    name = "envmap"
    Params = EnvmapParams

    def _key(self, scene: Scene, name: str, point, frame_index: int) -> str:
        params: EnvmapParams = self.params
        near, far = scene_extent(scene)
        return cache_key(format=MAP_FORMAT, technique="envmap", scene=scene.content_hash,
                         mirror=name, point=point, map=params.map,
                         resolution=params.resolution, near=near, far=far,
                         capture_frame=frame_index)

    def _capture_faces(self, scene: Scene, k: int, point, frame_index: int, faces=range(6),
                       out: np.ndarray | None = None) -> np.ndarray:
        """Cube faces of mirror k's map from the geometry of `frame_index` (6, S, S, 3)."""
        params: EnvmapParams = self.params
        near, far = scene_extent(scene)
        tris = scene.geometry(frame_index).all_triangles()
        flags = np.where(tris.surface >= scene.n_objects, FLAG_MIRROR, 0).astype(np.uint8)
        return capture_cube(scene, tris, flags, point, params.resolution,
                            scene.n_objects + k, near, far, faces, out)

    def _capture_whole(self, scene: Scene, k: int, point, frame_index: int,
                       cache: MapCache) -> tuple[np.ndarray, str, str | None]:
        """Mirror k's whole map at `frame_index` through the cache: (images, status, path)."""
        params: EnvmapParams = self.params
        name = scene.mirrors.names[k]
        key = self._key(scene, name, point, frame_index)
        expected = 6 if params.map == "cube" else 1
        parts = cache.load("envmap", key, MapShape(expected, params.resolution, 3),
                           lambda p, n=expected: _valid(p, n, params))
        status = "cached"
        if parts is None:
            status = "captured"
            faces = self._capture_faces(scene, k, point, frame_index)
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
                "reflect:capture_frame": str(frame_index),
                "reflect:resolution": str(params.resolution)})
        images = np.stack([np.stack([p[1]["R"], p[1]["G"], p[1]["B"]], axis=-1)
                           for p in parts]).astype(np.float32)
        return images, status, cache.path("envmap", key)

    def _wanted(self, frame_index: int) -> list[int]:
        """Per face (cube) or for the whole map (sphere), the frame its capture comes from."""
        params: EnvmapParams = self.params
        if params.map == "sphere":
            return [map_capture_frame(frame_index, params.update)]
        return face_capture_frames(frame_index, params.update, params.faces_per_frame)

    def precompute(self, scene: Scene, on_map=None, on_progress=None,
                   frame_index: int = 0) -> list[EnvmapRecord]:
        """Capture (or load from the cache) every reflector's map as used at `frame_index`;
        one record per map."""
        params: EnvmapParams = self.params
        unknown = sorted(set(params.capture) - set(scene.mirrors.names))
        if unknown:
            raise Problems([Problem(scene.source, f"technique.capture.{unknown[0]}",
                                    "no mirror of that name")])
        cache = MapCache(self.cache_dir)
        wanted = self._wanted(frame_index)
        at = wanted[0] if len(set(wanted)) == 1 else frame_index
        records = []
        for k, name in enumerate(scene.mirrors.names):
            point = capture_point(scene, k, params)
            start = time.perf_counter()
            images, status, path = self._capture_whole(scene, k, point, at, cache)
            for then in sorted(set(wanted) - {at}):
                images = self._capture_faces(scene, k, point, then,
                                             [f for f in range(6) if wanted[f] == then], images)
            record = EnvmapRecord(name, status, time.perf_counter() - start, path, point,
                                  images, list(wanted))
            records.append(record)
            if on_map is not None:
                on_map(record)
            if on_progress is not None:
                on_progress(k + 1, scene.mirrors.count)
        return records

    def _update(self, state: EnvmapState, frame_index: int) -> int:
        """Recapture what the update policy asks for at `frame_index`; the faces (cube) or
        maps (sphere) captured."""
        scene = state.scene
        wanted = self._wanted(frame_index)
        captured = 0
        for k, record in enumerate(state.maps):
            stale = [f for f in range(len(wanted)) if record.faces_frame[f] != wanted[f]]
            if not stale:
                continue
            if len(stale) == len(wanted) and len(set(wanted)) == 1:
                record.images, _, _ = self._capture_whole(scene, k, record.point, wanted[0],
                                                          state.cache)
            else:
                images = record.images.copy()
                for at in sorted({wanted[f] for f in stale}):
                    images = self._capture_faces(scene, k, record.point, at,
                                                 [f for f in stale if wanted[f] == at], images)
                record.images = images
            record.faces_frame = list(wanted)
            captured += len(stale)
        return captured

    def prepare(self, scene: Scene) -> EnvmapState:
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
        warn_stale(scene, "envmap", params.update)
        return EnvmapState(scene, records, box, seconds,
                           sum(r.status == "captured" for r in records), MapCache(self.cache_dir))

    def render(self, state: EnvmapState, frame_index: int, camera: Camera) -> Frame:
        scene = state.scene
        params: EnvmapParams = self.params
        t_capture = time.perf_counter()
        updated = self._update(state, frame_index)
        t_capture = time.perf_counter() - t_capture
        primary = render_primary(scene, frame_index, camera, state.primary)
        result = primary.frame
        t0 = time.perf_counter()
        bases = face_bases()
        map_kind = CUBE if params.map == "cube" else SPHERE_MAP
        dummy = np.zeros((1, 1, 3), np.float32)
        for k, record in enumerate(state.maps):
            images = record.images
            add_reflections(
                result.rgb, primary.buffers, result.surface, scene.n_objects + k,
                primary.triangles, int(scene.mirrors.kind[k]), scene.mirrors.params[k],
                scene.mirrors.reflectance[k], camera.eye, record.point, state.box[0],
                state.box[1], params.parallax == "box", map_kind,
                images if map_kind == CUBE else np.zeros((6, 1, 1, 3), np.float32),
                images[0] if map_kind == SPHERE_MAP else dummy, bases,
                params.filter == "bilinear")
        result.timings["lookup"] = time.perf_counter() - t0
        # frame 0's maps come from precompute (its own timing); later frames recapture here
        result.timings["capture"] = t_capture
        result.stats["faces_captured"] = (
            updated if frame_index else sum(len(r.faces_frame) for r in state.maps))
        result.stats["maps"] = len(state.maps)
        result.stats["maps_captured"] = state.maps_captured
        # one-time capture, done in prepare (never in a frame's time)
        result.stats["precompute_seconds"] = state.precompute_seconds
        return result


def _valid(parts, expected: int, params: EnvmapParams) -> bool:
    return len(parts) == expected and all(
        set(p[1]) >= {"R", "G", "B"} and p[1]["R"].shape == (params.resolution,) * 2
        for p in parts)
