"""The depth-preserving reflection maps technique class (parameters and method: the
package docstring)."""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

from ...camera import Camera
from ...frame import Frame
from ...geometry import reflection_matrix
from ...maps.cache import MapCache, MapShape, cache_key
from ...maps.surface import surface_colors
from ...maps.update import map_capture_frame
from ...maps.warp import WarpBuffers, fill_blend, stencil_box, warp_maps
from ...maps.zexel import (
    ZexelMap,
    capture_map,
    map_camera,
    mip_pyramid,
    mirror_frame,
    viewpoints,
)
from ...raster.primary import render_primary
from ...raster.rasterize import RasterWorkspace
from ...raster.rasterize.buffers import scratch
from ...scene.types import PLANAR, Scene, Triangles, scene_extent
from ..base import MapRecord, MapTechnique, precompute_logged, warn_non_planar, warn_stale
from . import DprmMaps, DprmParams

log = logging.getLogger("reflect")
MAP_FORMAT = 2  # 2: a T channel with each zexel's triangle


@dataclass
class DprmRecord(MapRecord):
    """One planar mirror's zexel maps."""

    index: int  # the mirror's index k
    maps: list[ZexelMap]
    plane: tuple[np.ndarray, float]  # (n, d) of the mirror, world
    viewpoints: np.ndarray  # (count, 3) the maps' viewpoints, world
    pyramids: dict[int, list[ZexelMap]] = field(default_factory=dict)  # map j -> mip levels
    capture_frame: int = 0  # the frame_index whose geometry the maps show
    # id of a map (or mip level) of this record -> its rows for the warp (see _payload)
    payloads: dict[int, np.ndarray] = field(default_factory=dict)


@dataclass
class DprmState:
    scene: Scene
    mirrors: list[DprmRecord]
    precompute_seconds: float
    triangles: Triangles  # the capture frame's triangles the maps' T channel indexes
    # per mirror index: (reflected colors, filled pixels) of the previous frame
    previous: dict[int, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    buffers: FrameBuffers | None = None  # per-frame arrays kept across frames
    # the primary pass's scratch, its triangle ids too (read only while the frame renders)
    buffers_raster: RasterWorkspace = field(
        default_factory=lambda: RasterWorkspace(ids=True))


class FrameBuffers:
    """The arrays a frame's warp and fill write, kept across frames (one screen size)."""

    def __init__(self, height: int, width: int) -> None:
        self.shape = (height, width)
        self.warp = WarpBuffers(height, width)
        # channels -> (H, W, channels) float32 the warp writes each reached pixel's zexel
        # row into (colour, or colour and triangle); other pixels hold stale rows, which
        # fill_blend never reads
        self.payloads: dict[int, np.ndarray] = {}
        self.spare: tuple[np.ndarray, np.ndarray] | None = None  # a free temporal pair
        # a mirror's stencil and the surface reconstruction's arrays (`_warp`,
        # `surface_colors`): each written where it is read, for each mirror
        self.workspace = RasterWorkspace()

    def payload(self, channels: int) -> np.ndarray:
        if channels not in self.payloads:
            self.payloads[channels] = np.zeros((*self.shape, channels), np.float32)
        return self.payloads[channels]


class Dprm(MapTechnique):
    name = "dprm"
    Params = DprmParams

    def precompute(self, scene: Scene, on_map=None, on_progress=None,
                   frame_index: int = 0) -> list[DprmRecord]:
        """Capture (or load) every planar mirror's maps as used at `frame_index`; one record
        per mirror. on_progress(maps done, maps in all) follows the capture map by map."""
        p: DprmMaps = self.params.maps
        total = p.count * int(np.count_nonzero(scene.mirrors.kind == PLANAR))
        done = 0
        cache = MapCache(self.cache_dir)
        near, far = scene_extent(scene)
        at = map_capture_frame(frame_index, self.params.update)
        n_triangles = scene.geometry(at).all_triangles().count
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
                            layout=p.layout, radius=radius, spread=p.spread, near=near, far=far,
                            capture_frame=at)
            start = time.perf_counter()
            parts = cache.load("dprm", key, MapShape(p.count, p.resolution, 5),
                               lambda parts: _valid(parts, p, n_triangles))
            status = "cached"
            if parts is None:
                status = "captured"
                maps = []
                for cam in cams:
                    maps.append(capture_map(scene, k, cam, at))
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
                    "reflect:near": repr(near), "reflect:far": repr(far),
                    "reflect:capture_frame": str(at)}, [
                    {"reflect:viewpoint": _numbers(cam.eye),
                     "reflect:view_matrix": _numbers(cam.view_matrix()),
                     "reflect:projection_matrix": _numbers(cam.projection_matrix()),
                     "reflect:fov_y": repr(cam.fov_y)} for cam in cams])
            else:
                # contiguous: the warp reads them every frame
                maps = [ZexelMap(cam, np.stack([c["R"], c["G"], c["B"]], axis=-1),
                                 np.ascontiguousarray(c["Z"], np.float32),
                                 c["T"].astype(np.int32))
                        for cam, (_, c, _) in zip(cams, parts, strict=True)]
                done += len(maps)
                if on_progress is not None:
                    on_progress(done, total)
            record = DprmRecord(name, status, time.perf_counter() - start,
                                cache.path("dprm", key), k, maps,
                                (mf.normal, float(-mf.normal @ mf.center)), points,
                                capture_frame=at)
            records.append(record)
            if on_map is not None:
                on_map(record)
        return records

    def prepare(self, scene: Scene) -> DprmState:
        warn_non_planar(scene, "dprm")
        records, seconds = precompute_logged(self, scene, "dprm")
        warn_stale(scene, "dprm", self.params.update)
        return DprmState(scene, records, seconds, scene.geometry(0).all_triangles())

    def _update(self, state: DprmState, frame_index: int) -> int:
        """Recapture every mirror's maps if the update policy asks for another capture frame
        than theirs at `frame_index`; the maps captured."""
        at = map_capture_frame(frame_index, self.params.update)
        if all(r.capture_frame == at for r in state.mirrors):
            return 0
        state.mirrors = self.precompute(state.scene, frame_index=frame_index)
        state.triangles = state.scene.geometry(at).all_triangles()
        return sum(len(r.maps) for r in state.mirrors)

    def render(self, state: DprmState, frame_index: int, camera: Camera) -> Frame:
        scene = state.scene
        params: DprmParams = self.params
        t_capture = time.perf_counter()
        captured = self._update(state, frame_index)
        t_capture = time.perf_counter() - t_capture
        primary = render_primary(scene, frame_index, camera, state.buffers_raster)
        result = primary.frame
        self.last_lod_level = 0
        h, w = result.surface.shape
        if state.buffers is None or state.buffers.shape != (h, w):
            state.buffers = FrameBuffers(h, w)
            state.previous.clear()
        holes = np.zeros((h, w), np.float32)
        warp_s = fill_s = 0.0
        used, warped = 0, 0
        for record in state.mirrors:
            k = record.index
            # the kept stencil, written whole for each mirror
            stencil = np.equal(result.surface, scene.n_objects + k,
                               out=scratch(state.buffers.workspace, "stencil", (h, w), np.bool_))
            _, box = stencil_box(stencil)
            if box is None:
                continue
            t0 = time.perf_counter()
            reflected, best_id, n_maps, n_zexels = self._warp(
                record, camera, stencil, scene, state.triangles, state.buffers, box)
            t1 = time.perf_counter()
            prev = state.previous.get(k) if params.fill.temporal else None
            if params.fill.temporal:
                # the previous frame's pair is read while this frame's is written: two pairs
                spare = state.buffers.spare
                if spare is None:
                    spare = (np.empty((h, w, 3), np.float32), np.empty((h, w), bool))
                state.buffers.spare = prev
                save_rgb, save_filled = spare
            empty = (np.empty((0, 0, 3), np.float32), np.empty((0, 0), bool))
            if not params.fill.temporal:
                save_rgb, save_filled = empty
            prev_rgb, prev_filled = prev if prev is not None else empty
            fill_blend(stencil, best_id, reflected, prev is not None,
                        prev_rgb, prev_filled, params.fill.temporal, save_rgb, save_filled,
                        scene.background, scene.mirrors.reflectance[k], result.rgb, holes)
            if params.fill.temporal:
                state.previous[k] = (save_rgb, save_filled)
            fill_s += time.perf_counter() - t1
            warp_s += t1 - t0
            used += n_maps
            warped += n_zexels
        mirror_pixels = int(np.count_nonzero(result.mirror_mask))  # surface >= n_objects
        hole_count = int(np.count_nonzero(holes))
        result.extra["holes"] = holes
        result.timings.update({"warp": warp_s, "fill": fill_s, "capture": t_capture})
        result.stats.update({"maps_used": used, "zexels_warped": warped,
                             # one-time capture, done in prepare (never in a frame's time)
                             "precompute_seconds": state.precompute_seconds,
                             "maps_captured": captured if frame_index
                             else sum(len(r.maps) for r in state.mirrors),
                             "lod_level": getattr(self, "last_lod_level", 0),
                             # raw: mirror pixels no zexel reached, including those
                             # whose reflection is the background (the bench's
                             # hole_fraction counts only where geometry should show)
                             "unreached": hole_count,
                             "unreached_fraction": float(hole_count / max(mirror_pixels, 1))})
        return result

    def _lod(self, record: DprmRecord, chosen, stencil: np.ndarray):
        """The coarsest mip level that still has a zexel per mirror pixel across the mirror
        (the maps' frustums cover the mirror, so their side spans about its width)."""
        pixels_across = math.sqrt(max(int(stencil.sum()), 1))
        level = max(0, int(math.floor(math.log2(
            record.maps[0].depth.shape[0] / pixels_across))))
        maps = []
        for j in chosen:
            if j not in record.pyramids:
                record.pyramids[j] = mip_pyramid(record.maps[j])
            pyramid = record.pyramids[j]
            maps.append(pyramid[min(level, len(pyramid) - 1)])
        return maps, level

    def _warp(self, record: DprmRecord, camera: Camera, stencil: np.ndarray,
              scene: Scene | None = None, triangles=None, buffers: FrameBuffers | None = None,
              box=None):
        """Reflected colors over the stencil (unreached pixels hold anything), the warp's id
        per pixel (-1: no zexel reached it), maps and zexels warped; with `buffers`, views of
        its arrays. `box`: the stencil's (x0, x1, y0, y1) if the caller has it."""
        params: DprmParams = self.params
        k_maps: list[ZexelMap] = record.maps
        n, d = record.plane
        # equations 1 and 2: the eye mirrored across the plane
        reflect = reflection_matrix(n, d)
        mirrored_eye = camera.eye - 2.0 * (n @ camera.eye + d) * n
        order_by_distance = np.argsort(
            np.linalg.norm(record.viewpoints - mirrored_eye, axis=1), kind="stable")
        chosen = order_by_distance[: params.maps.per_frame]
        maps = [k_maps[j] for j in chosen]
        level = 0
        if params.maps.lod:
            maps, level = self._lod(record, chosen, stencil)
        self.last_lod_level = level
        h, w = stencil.shape
        if box is None:
            _, box = stencil_box(stencil)
        # what each pixel carries from its zexel: its colour (and, to shade its own point
        # of the zexel's triangle, the triangle), written by the warp itself
        surface = params.reconstruct == "surface" and scene is not None
        payloads = [_payload(record, m, surface) for m in maps]
        channels = 4 if surface else 3
        out = (buffers.payload(channels) if buffers is not None
               else np.zeros((h, w, channels), np.float32))
        _, best_id, stride, zexels = warp_maps(maps, camera, reflect, mirrored_eye, stencil,
                                               params.fill.splat, params.occlusion == "ordered",
                                               buffers.warp if buffers is not None else None,
                                               box, payloads, out)
        reflected = out[:, :, :3]
        if surface and box is not None:
            x0, x1, y0, y1 = box
            ws = buffers.workspace if buffers is not None else None
            tri = scratch(ws, "surface_triangle", (h, w), np.int32)
            tri.fill(-1)  # (kept: cleared whole, as surface_colors reads every pixel)
            # the reached pixels' triangles (exact in float32), -1 elsewhere
            np.copyto(tri[y0:y1, x0:x1], out[y0:y1, x0:x1, 3], casting="unsafe",
                      where=best_id[y0:y1, x0:x1] >= 0)
            shaded, ok = surface_colors(tri, camera, reflect, mirrored_eye, (n, d), triangles,
                                        scene, ws)
            # ok: pixels a zexel reached, inside the box
            np.copyto(reflected[y0:y1, x0:x1], shaded[y0:y1, x0:x1],
                      where=ok[y0:y1, x0:x1, None])
        return reflected, best_id, len(chosen), zexels


def _payload(record: DprmRecord, zmap: ZexelMap, surface: bool) -> np.ndarray:
    """A map's rows for the warp to carry: colour (n, 3), or colour and triangle (n, 4,
    float32: triangle ids are exact below 2^24, as in the map cache), kept per map."""
    if not surface:
        return zmap.color.reshape(-1, 3)
    key = id(zmap)
    if key not in record.payloads:
        n = zmap.depth.size
        rows = np.empty((n, 4), np.float32)
        rows[:, :3] = zmap.color.reshape(n, 3)
        rows[:, 3] = zmap.triangle.reshape(n)
        record.payloads[key] = rows
    return record.payloads[key]


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
