"""The engines' hybrid chain for screen-space misses: rerender or a cube map, else base.

Shared by `ssr` and `ppr`. `source` codes per pixel: 0 not a mirror, 1 screen space,
2 rerender, 3 envmap, 4 base only ((1 - r) * base).
"""

from __future__ import annotations

import numpy as np

from ...raster.rasterize import RasterWorkspace
from ...raster.rasterize.buffers import scratch
from ...scene.types import PLANAR, Scene

NOT_MIRROR, SCREEN, RERENDER, ENVMAP, BASE = 0, 1, 2, 3, 4


class Fallback:
    def __init__(self, kind: str, threads: int, cache_dir: str | None) -> None:
        self.kind = kind
        self.threads = threads
        self.cache_dir = cache_dir
        self.helper = None
        self.state = None
        # scratch kept across frames (None: fresh every frame): the envmap lookups' ids
        self.workspace: RasterWorkspace | None = RasterWorkspace()

    def prepare(self, scene: Scene) -> None:
        if self.kind == "envmap":
            from ..envmap import EnvmapParams
            from ..envmap.technique import Envmap

            self.helper = Envmap(EnvmapParams(parallax="box"), self.threads, self.cache_dir)
            self.state = self.helper.prepare(scene)
        elif self.kind == "rerender":
            from ..rerender import RerenderParams
            from ..rerender.technique import Rerender

            self.helper = Rerender(RerenderParams(max_depth=1), self.threads, self.cache_dir)
            self.state = self.helper.prepare(scene)

    def apply(self, scene: Scene, primary, camera, hit: np.ndarray, rgb: np.ndarray,
              timings: dict) -> np.ndarray:
        """Colour the missed mirror pixels of `rgb` (they hold (1 - r) * base); in place.
        Returns the `source` channel (float32)."""
        import time

        surface = primary.frame.surface
        mirror = primary.frame.mirror_mask
        miss = mirror & (hit == 0)
        # the channel, fresh (the frame keeps it): made in float32 (were int64 temporaries)
        source = np.where(hit != 0, np.float32(SCREEN), np.float32(BASE))
        source[~mirror] = NOT_MIRROR
        start = time.perf_counter()
        if self.kind == "rerender" and miss.any():
            stats = {"passes": 0, "triangles_rasterized": 0, "pass_seconds": []}
            self.helper._reflect(scene, primary.geometry, primary.flags, camera, 1,
                                 np.eye(4), camera.eye, surface, miss, rgb, stats)
            planar = np.isin(surface - scene.n_objects,
                             np.flatnonzero(scene.mirrors.kind == PLANAR))
            source[miss & planar] = RERENDER
        elif self.kind == "envmap" and miss.any():
            from ...maps.cube import face_bases
            from ...maps.lookup import CUBE, add_reflections

            # missed pixels hold (1 - r) * base and lookups add r * map, in place; the
            # lookups run on the missed pixels only (their surface ids, -1 elsewhere: every
            # pixel written, so an earlier frame's ids are never read)
            missed_ids = scratch(self.workspace, "missed_ids", surface.shape, surface.dtype)
            missed_ids.fill(-1)
            np.copyto(missed_ids, surface, where=miss)
            dummy = np.zeros((1, 1, 3), np.float32)
            box = self.state.box
            for k, record in enumerate(self.state.maps):
                add_reflections(rgb, primary.buffers, missed_ids, scene.n_objects + k,
                                primary.triangles, int(scene.mirrors.kind[k]),
                                scene.mirrors.params[k], scene.mirrors.reflectance[k],
                                camera.eye, record.point, box[0], box[1], True, CUBE,
                                record.images, dummy, face_bases(), True)
            source[miss] = ENVMAP
        timings["fallback"] = time.perf_counter() - start
        return source
