"""Triangle intersection through Embree (embreex), split over threads (Embree drops the GIL)."""

from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

_POOL: ThreadPoolExecutor | None = None


def _pool() -> ThreadPoolExecutor:
    """One long-lived pool: starting threads per call costs more than small batches take."""
    global _POOL
    if _POOL is None:
        _POOL = ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 1))
    return _POOL


class TriangleScene:
    """An Embree scene over world-space triangles (T, 3, 3); empty scenes never hit."""

    def __init__(self, corners: np.ndarray) -> None:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        start = time.perf_counter()
        self.count = int(corners.shape[0])
        self._scene = None
        if self.count:
            self._scene = rtcore_scene.EmbreeScene()
            TriangleMesh(self._scene, np.ascontiguousarray(corners, dtype=np.float32))
            # embree commits lazily on the first query; force it so build time is measured here
            self._scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32), output=1)
        self.build_seconds = time.perf_counter() - start

    def intersect(
        self, origins: np.ndarray, directions: np.ndarray, tfar: np.ndarray, threads: int = 1
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Nearest hit per ray: (t, primitive id (-1 on a miss), u, v), t = inf on a miss.

        u and v are the barycentric weights of corners 1 and 2. t is in units of the
        direction's length; rays start at their origin (tnear = 0) and stop at tfar.
        """
        n = origins.shape[0]
        t = np.full(n, np.inf, np.float32)
        prim = np.full(n, -1, np.int32)
        u = np.zeros(n, np.float32)
        v = np.zeros(n, np.float32)
        if self._scene is None or n == 0:
            return t, prim, u, v
        origins = np.ascontiguousarray(origins, dtype=np.float32)
        directions = np.ascontiguousarray(directions, dtype=np.float32)
        tfar = np.ascontiguousarray(tfar, dtype=np.float32)

        def run(a: int, b: int) -> None:
            res = self._scene.run(origins[a:b], directions[a:b], dists=tfar[a:b].copy(), output=1)
            hit = res["primID"] >= 0
            prim[a:b] = res["primID"]
            t[a:b] = np.where(hit, res["tfar"], np.inf)
            u[a:b] = res["u"]
            v[a:b] = res["v"]

        chunks = max(1, min(threads, n // 4096 or 1))
        bounds = np.linspace(0, n, chunks + 1).astype(int)
        if chunks == 1:
            run(0, n)
        else:
            list(_pool().map(run, bounds[:-1], bounds[1:]))
        return t, prim, u, v
