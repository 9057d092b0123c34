"""Wavefront Whitted tracing of one frame: primary rays, then one wave per mirror bounce, all
in one parallel loop over segments of rays (`wave.trace_segments`).

A ray's color accumulates along its path: at an object, weight * shade; at a mirror,
weight * (1 - r) * base, and the weight becomes weight * r for the reflected ray; on a miss,
weight * background. A mirror met after `max_depth` bounces adds only (1 - r) * base (its
reflection is not followed), so max_depth = 0 draws mirrors as their base color.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numba
import numpy as np

from ..camera import Camera
from ..frame import Frame
from ..scene.types import Geometry, Scene
from .analytic import has_analytic, quad_edges, screen_boxes
from .embree import TriangleScene
from .rays import camera_rays, primary_rays
from .resolve import planar_units
from .wave import trace_segments

_FAR_AWAY = np.float32(1e30)  # tfar of reflected rays
SEGMENT_RAYS = 4096  # about this many rays per segment (whole image rows): one work item


class TraceBuffers:
    """Work arrays of the tracer kept across frames, by name: a frame's fresh arrays cost more
    in first-touch page faults than the tracing they hold (a 640x480 frame: about 16 of
    48 ms, 1 thread). Only the frame's own outputs (rgb, depth, ids) are new every frame."""

    def __init__(self) -> None:
        self._arrays: dict[str, np.ndarray] = {}
        self._edges: tuple[np.ndarray, np.ndarray] | None = None  # (mirror params, edges)
        self._units: tuple[np.ndarray, np.ndarray] | None = None  # (mirror params, units)

    def quad_edges(self, kind: np.ndarray, params: np.ndarray) -> np.ndarray:
        """analytic.quad_edges of the scene's mirrors, made once (the mirrors' parameters
        are the scene's: the same array every frame)."""
        if self._edges is None or self._edges[0] is not params:
            self._edges = (params, quad_edges(kind, params))
        return self._edges[1]

    def planar_units(self, kind: np.ndarray, params: np.ndarray) -> np.ndarray:
        """resolve.planar_units of the scene's mirrors, made once (as quad_edges)."""
        if self._units is None or self._units[0] is not params:
            self._units = (params, planar_units(kind, params))
        return self._units[1]

    def get(self, name: str, n: int, dtype, width: int = 0) -> np.ndarray:
        """The first n rows of buffer `name` ((n,) or (n, width)), grown when too small;
        contents are whatever the last frame left."""
        a = self._arrays.get(name)
        shape = (n, width) if width else (n,)
        if a is None or a.shape[0] < n or a.shape[1:] != shape[1:] or a.dtype != dtype:
            a = self._arrays[name] = np.empty(shape, dtype)
        return a[:n]

    def rays(self, name: str, n: int) -> tuple[np.ndarray, ...]:
        """(origins, directions, weights, slots) of n rays."""
        return (self.get(name + "_o", n, np.float32, 3), self.get(name + "_d", n, np.float32, 3),
                self.get(name + "_w", n, np.float32, 3), self.get(name + "_slot", n, np.int64))

    def hits(self, name: str, n: int) -> tuple[np.ndarray, ...]:
        """(t, primitive or mirror index, u, v) of n rays."""
        return (self.get(name + "_t", n, np.float32), self.get(name + "_prim", n, np.int32),
                self.get(name + "_u", n, np.float32), self.get(name + "_v", n, np.float32))


@dataclass
class Accelerators:
    """Embree scenes for one geometry state: objects, and mesh mirrors' triangles."""

    key: tuple
    objects: TriangleScene
    mirrors: TriangleScene
    mirror_corners: np.ndarray  # (Tm, 3, 3) mesh mirror triangles, in Embree's order
    mirror_normals: np.ndarray
    mirror_surface: np.ndarray
    buffers: TraceBuffers = field(default_factory=TraceBuffers)

    @property
    def build_seconds(self) -> float:
        return self.objects.build_seconds + self.mirrors.build_seconds


def build_accelerators(geometry: Geometry, fast: bool = False) -> Accelerators:
    """The frame's Embree scenes (objects, exact mirror triangles); `fast`: built with
    Mitsuba 3's settings instead of robust ones (embree.TriangleScene)."""
    m = geometry.mirror_tris
    exact = geometry.mirror_exact
    corners = np.ascontiguousarray(m.corners[exact])
    return Accelerators(
        geometry.key,
        TriangleScene(geometry.objects.corners, fast),
        TriangleScene(corners, fast),
        corners,
        np.ascontiguousarray(m.normals[exact]),
        np.ascontiguousarray(m.surface[exact]),
    )


def trace_frame(
    scene: Scene,
    geometry: Geometry,
    accel: Accelerators,
    camera: Camera,
    max_depth: int,
    samples: int = 1,
    threads: int = 1,
) -> Frame:
    """Ray trace one frame; `samples` x `samples` rays per pixel on a regular grid.

    The frame's segments (a few image rows of rays each, `wave.trace_segments`) are handed
    out one at a time to whichever thread is free (not one fixed share per thread): on a
    busy machine a thread that loses its core no longer holds the others up. Every ray
    writes only its own outputs, so results do not depend on who traced what."""
    start = time.perf_counter()
    tracer = _Segments(scene, geometry, accel, camera, threads)
    h, w = camera.height, camera.width
    spp = samples * samples
    n = h * w * spp
    color = np.empty((n, 3), np.float32)  # the frame's rgb: the first wave writes every row
    depth = np.empty(n, np.float32)
    surface = np.empty(n, np.int32)
    reflected_hit = np.zeros(n, np.float32)  # first reflected ray hit geometry
    traced = tracer.run(samples, max_depth, color, depth, surface, reflected_hit)
    if spp == 1:  # the mean of one sample is the sample (bit for bit): no float64 pass
        rgb = color.reshape(h, w, 3)
        reflected_hit = reflected_hit.reshape(h, w)
    else:
        rgb = color.reshape(h, w, spp, 3).mean(axis=2, dtype=np.float64).astype(np.float32)
        reflected_hit = reflected_hit.reshape(h, w, spp).mean(axis=2).astype(np.float32)
        # Z, A and ids come from the pixel-center ray, traced once more
        depth = np.empty(h * w, np.float32)
        surface = np.empty(h * w, np.int32)
        scratch = accel.buffers.get("center_color", h * w, np.float32, 3)
        # no bounce (max_depth 0): reflected_hit is never written; handed flat, as in the
        # first call (a 2-D one compiled trace_segments a second time, 3 minutes)
        traced += tracer.run(1, 0, scratch, depth, surface, reflected_hit.reshape(-1))
    timings = {"segments": tracer.seconds, "trace": time.perf_counter() - start}
    return Frame(
        rgb=rgb,
        depth=depth.reshape(h, w),
        surface=surface.reshape(h, w),
        mirror_mask=surface.reshape(h, w) >= scene.n_objects,
        # what a mirror pixel's reflection should show: 1 where its reflected ray meets
        # geometry (an object or another mirror), 0 where it leaves for the background (the
        # fraction of samples that do, with supersampling); techniques' holes count against it
        extra={"reflected_hit": reflected_hit} if max_depth >= 1 else {},
        timings=timings,
        stats={"rays": int(traced)},
    )


class _Segments:
    """trace_segments' arguments that stay the same over a frame, and its calls. Rays
    alternate between the kept ray buffers "a" and "b": a segment's worth of rows per thread
    (trace_segments' per_worker scratch), or with the embreex fallback the whole frame's
    rays (a segment's reflected rays stay in its part of that range)."""

    def __init__(self, scene: Scene, geometry: Geometry, accel: Accelerators, camera: Camera,
                 threads: int) -> None:
        self.camera, self.accel, self.threads = camera, accel, threads
        self.seconds = 0.0
        o, m = geometry.objects, scene.mirrors
        self.surfaces = (
            o.corners, o.uvs, o.normals, o.material, o.surface, accel.mirror_corners,
            accel.mirror_normals, accel.mirror_surface, m.kind, m.params, m.reflectance,
            m.base, scene.n_objects, scene.materials.mat_i, scene.materials.mat_f,
            scene.materials.texels, scene.lights.light_f, scene.shading, scene.ambient,
            scene.background, accel.buffers.planar_units(m.kind, m.params))
        self.analytic = (has_analytic(m.kind), m.kind,
                         np.ascontiguousarray(m.params, dtype=np.float64),
                         accel.buffers.quad_edges(m.kind, m.params),
                         screen_boxes(m.kind, m.params, camera))
        # embreex traces outside the kernel (no Embree library for it, or numba's JIT off)
        self.fallback = any(s.count and not s.handle for s in (accel.objects, accel.mirrors))

    def run(self, samples: int, max_depth: int, color, depth, surface, reflected_hit) -> int:
        """The camera's rays and max_depth bounces; returns how many rays were traced."""
        t0 = time.perf_counter()
        cam, b = self.camera, self.accel.buffers
        per_row = cam.width * samples * samples
        rows = max(1, round(SEGMENT_RAYS / per_row))
        seg_len = rows * per_row
        n = cam.height * per_row
        segments = -(-cam.height // rows)
        counts = np.full(segments, seg_len, np.int64)
        counts[-1] = n - (segments - 1) * seg_len
        traced = np.zeros((segments, max_depth + 1), np.int64)
        threads = numba.get_num_threads()
        # the kernels take a segment through all its waves: a segment's worth of scratch per
        # thread; the embreex fallback traces a wave of the whole frame between calls
        scratch = n if self.fallback else threads * seg_len
        buffers = (b.rays("a", scratch), b.rays("b", scratch))
        hits_o, hits_m = b.hits("objects", scratch), b.hits("mirrors", scratch)
        args = [seg_len, counts, rows, camera_rays(cam, samples), buffers,
                np.array([cam.far - cam.near, _FAR_AWAY], np.float32),
                (self.accel.objects.handle, bool(self.accel.objects.count), *hits_o),
                (self.accel.mirrors.handle, bool(self.accel.mirrors.count), *hits_m),
                (*self.analytic, b.get("analytic_t", scratch, np.float32),
                 b.get("analytic_k", scratch, np.int32)),
                self.surfaces, (0, max_depth), max_depth,
                ((depth, surface), (b.get("hit_t", scratch, np.float32),
                                    b.get("hit_surface", scratch, np.int32))),
                color, np.float32(cam.near), reflected_hit, traced, threads,
                not self.fallback]
        if not self.fallback:
            trace_segments(*args)  # one item per thread, segments claimed (parallel.py)
        else:  # one wave a call, embreex tracing its rays first
            primary_rays(cam, samples, out=buffers[0][:2])
            args[2] = 0
            for bounce in range(max_depth + 1):
                if not counts.any():
                    break
                self._embreex(seg_len, counts, buffers[bounce % 2], args[5][min(bounce, 1)],
                              hits_o, hits_m)
                args[10] = (bounce, bounce)
                trace_segments(*args)
        self.seconds += time.perf_counter() - t0
        return int(traced.sum())

    def _embreex(self, seg_len, counts, rays, tfar, hits_o, hits_m) -> None:
        """The hits of a wave's rays by the embreex binding, into the hit arrays."""
        rows = np.concatenate([np.arange(k * seg_len, k * seg_len + c)
                               for k, c in enumerate(counts)])
        for scene, out in ((self.accel.objects, hits_o), (self.accel.mirrors, hits_m)):
            if scene.count:
                got = scene.intersect(rays[0][rows], rays[1][rows],
                                      np.full(rows.shape[0], tfar, np.float32), self.threads)
                for a, g in zip(out, got, strict=True):
                    a[rows] = g
