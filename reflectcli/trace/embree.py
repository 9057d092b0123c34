"""Triangle intersection through Embree 4: the library shipped inside the embreex wheel,
called straight from numba kernels (`rtcIntersect8` on packets of 8 rays, packets split
over numba's threads), no Python loop and no per-call array copies.

The scene is built as embreex builds it (one triangle geometry of unshared float3 vertices,
scene flag ROBUST, default build quality), so hits are bit-identical to embreex's
`EmbreeScene.run`; when the library cannot be found the embreex binding is used instead.
`fast` scenes are built as Mitsuba 3 builds its own (no scene flag, high build quality:
`src/render/scene_embree.inl`): a like-for-like speed comparison with it, at the price of
Embree's robust traversal (a ray may slip through the shared edge of two triangles).
"""

from __future__ import annotations

import ctypes
import glob
import os
import time
import weakref
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
from numba import njit, prange, types

_POOL: ThreadPoolExecutor | None = None
_LANES = 8
# RTCRayHit8: 12 ray + 10 hit fields (Ng xyz, u, v, primID, geomID, instID, instPrimID of
# Embree 4 with one instance level) of 8 lanes each
_PACKET_FLOATS = 22 * _LANES
# where each field's lanes start in a packet (unsigned: see intersect_range)
_F = tuple(np.uint64(f * _LANES) for f in range(22))
_ROBUST = 1 << 2  # RTC_SCENE_FLAG_ROBUST (embreex's default)
_QUALITY_HIGH = 2  # RTC_BUILD_QUALITY_HIGH (Mitsuba 3's, with no scene flag)
_TRIANGLE, _INDEX, _VERTEX, _UINT3, _FLOAT3 = 0, 0, 1, 0x5003, 0x9003

_rtc_intersect8 = types.ExternalFunction(
    "rtcIntersect8", types.void(types.intp, types.intp, types.intp, types.intp))


class _Embree:
    """The Embree library (ctypes for building, its symbols loaded for numba) and one device."""

    def __init__(self, path: str) -> None:
        import llvmlite.binding as llvm

        llvm.load_library_permanently(path)  # numba's cached kernels resolve rtcIntersect8
        lib = self.lib = ctypes.CDLL(path)
        p, u, i, z = ctypes.c_void_p, ctypes.c_uint, ctypes.c_int, ctypes.c_size_t
        for name, res, args in [
            ("rtcNewDevice", p, [ctypes.c_char_p]), ("rtcNewScene", p, [p]),
            ("rtcSetSceneFlags", None, [p, i]), ("rtcNewGeometry", p, [p, i]),
            ("rtcSetNewGeometryBuffer", p, [p, i, u, i, z, z]),
            ("rtcCommitGeometry", None, [p]), ("rtcAttachGeometry", u, [p, p]),
            ("rtcReleaseGeometry", None, [p]), ("rtcCommitScene", None, [p]),
            ("rtcReleaseScene", None, [p]), ("rtcSetSceneBuildQuality", None, [p, i]),
            ("rtcGetSceneFlags", i, [p]),
        ]:
            fn = getattr(lib, name)
            fn.restype, fn.argtypes = res, args
        self.device = lib.rtcNewDevice(None)
        if not self.device:
            raise OSError("Embree: no device")

    def scene(self, corners: np.ndarray, fast: bool = False) -> int:
        """A committed scene over (T, 3, 3) float32 triangles; its handle. `fast`: Mitsuba
        3's settings (no ROBUST flag, high build quality), else embreex's."""
        lib, nt = self.lib, corners.shape[0]
        scene = lib.rtcNewScene(self.device)
        lib.rtcSetSceneFlags(scene, 0 if fast else _ROBUST)
        if fast:
            lib.rtcSetSceneBuildQuality(scene, _QUALITY_HIGH)
        geom = lib.rtcNewGeometry(self.device, _TRIANGLE)
        vp = lib.rtcSetNewGeometryBuffer(geom, _VERTEX, 0, _FLOAT3, 16, nt * 3)
        vertices = np.ctypeslib.as_array(ctypes.cast(vp, ctypes.POINTER(ctypes.c_float)),
                                         (nt * 3, 4))
        vertices[:, :3] = corners.reshape(-1, 3)
        ip = lib.rtcSetNewGeometryBuffer(geom, _INDEX, 0, _UINT3, 12, nt)
        indices = np.ctypeslib.as_array(ctypes.cast(ip, ctypes.POINTER(ctypes.c_uint32)),
                                        (nt * 3,))
        indices[:] = np.arange(nt * 3, dtype=np.uint32)
        lib.rtcCommitGeometry(geom)
        lib.rtcAttachGeometry(scene, geom)
        lib.rtcReleaseGeometry(geom)
        lib.rtcCommitScene(scene)
        return int(scene)

    def scene_flags(self, scene: int) -> int:
        """The scene's RTCSceneFlags (the tests read which settings a scene was built
        with)."""
        return int(self.lib.rtcGetSceneFlags(scene))


_EMBREE: _Embree | None | bool = None


def _embree() -> _Embree | None:
    """The library inside the embreex wheel (None when it is not found there, or with numba's
    JIT off, as `make coverage` runs: then embreex traces)."""
    global _EMBREE
    if _EMBREE is None and numba.config.DISABLE_JIT:
        _EMBREE = False  # interpreted, the packet kernel cannot call into the library
    if _EMBREE is None:
        import embreex

        site = os.path.dirname(os.path.dirname(os.path.abspath(embreex.__file__)))
        found = sorted(glob.glob(os.path.join(site, "embreex.libs", "libembree4*")))
        try:
            _EMBREE = _Embree(found[0]) if found else False
        except OSError:
            _EMBREE = False
    return _EMBREE or None


def _pool() -> ThreadPoolExecutor:
    """One long-lived pool (the embreex fallback): starting threads per call costs more than
    small batches take."""
    global _POOL
    if _POOL is None:
        _POOL = ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 1))
    return _POOL


@njit(cache=True, parallel=True, nogil=True)
def _intersect(scene, origins, directions, tfar, chunks, t, prim, u, v):
    """Nearest hit of each ray (`intersect_range`), the rays split into `chunks` contiguous
    runs of whole packets."""
    n = origins.shape[0]
    packets = (n + _LANES - 1) // _LANES
    for c in prange(chunks):
        buf, off = packet_buffer()
        a = min(n, c * packets // chunks * _LANES)
        b = min(n, (c + 1) * packets // chunks * _LANES)
        intersect_range(scene, origins, directions, tfar, a, b, t, prim, u, v, buf, off)


@njit(cache=True)
def packet_buffer():
    """(buf, off): an RTCRayHit8 (structure of arrays, 22 fields of 8 lanes) at buf[off:],
    64-byte aligned, its valid mask (8 ints) after it; the fields Embree only reads and that
    are the same for every ray are set here once, as embreex sets them: tnear 0, time 0,
    mask all ones (every geometry), id 0, flags 0."""
    buf = np.empty(_PACKET_FLOATS + _LANES + 16, np.float32)
    ints = buf.view(np.int32)
    off = ((64 - buf.ctypes.data % 64) % 64) // 4
    for lane in range(_LANES):
        buf[off + 3 * _LANES + lane] = 0.0  # tnear
        buf[off + 7 * _LANES + lane] = 0.0  # time
        ints[off + 9 * _LANES + lane] = -1  # mask
        ints[off + 10 * _LANES + lane] = 0  # id
        ints[off + 11 * _LANES + lane] = 0  # flags
    return buf, off


@njit(cache=True, inline="always")
def intersect_range(scene, origins, directions, tfar, a, b, t, prim, u, v, buf, off):
    """Nearest hit of rays a .. b - 1 through rtcIntersect8, on packets of 8 consecutive
    rays (image rows: coherent primary rays) in `packet_buffer`'s (buf, off). Each packet
    gets its rays' origins, directions and tfar (tfar[i], or tfar[0] for every ray when tfar
    has one entry) and invalid hit ids; t, primitive id, u, v (inf, -1, 0, 0 on a miss) are
    written at the rays' indices. Embree's packet and single-ray paths give the same hits to
    the bit, so the packets' make-up does not matter (test_embree_bruteforce.py)."""
    ints = buf.view(np.int32)
    address = buf.ctypes.data + 4 * off
    valid = off + _PACKET_FLOATS
    one_tfar = tfar.shape[0] == 1
    # (indices unsigned, as in resolve_range.) Lane q of field f (of the structure's 22) is
    # at off + f * _LANES + q.
    lane0 = np.uint64(off)
    for first in range(a, b, _LANES):
        lanes = min(_LANES, b - first)
        for lane in range(_LANES):
            ints[valid + lane] = -1 if lane < lanes else 0
        for lane in range(lanes):
            i = np.uint64(first + lane)
            q = lane0 + np.uint64(lane)
            buf[q + _F[0]] = origins[i, 0]
            buf[q + _F[1]] = origins[i, 1]
            buf[q + _F[2]] = origins[i, 2]
            buf[q + _F[4]] = directions[i, 0]
            buf[q + _F[5]] = directions[i, 1]
            buf[q + _F[6]] = directions[i, 2]
            buf[q + _F[8]] = tfar[0] if one_tfar else tfar[i]
            ints[q + _F[17]] = -1  # primID
            ints[q + _F[18]] = -1  # geomID
            ints[q + _F[19]] = -1  # instID
        _rtc_intersect8(address + 4 * _PACKET_FLOATS, scene, address, 0)
        for lane in range(lanes):
            i = np.uint64(first + lane)
            q = lane0 + np.uint64(lane)
            p = ints[q + _F[17]]
            prim[i] = p
            if p >= 0:
                t[i] = buf[q + _F[8]]
                u[i] = buf[q + _F[15]]
                v[i] = buf[q + _F[16]]
            else:
                t[i] = np.inf
                u[i] = 0.0
                v[i] = 0.0


class TriangleScene:
    """An Embree scene over world-space triangles (T, 3, 3); empty scenes never hit.
    `fast`: built with Mitsuba 3's settings (see the module's docstring); the embreex
    binding (numba's JIT off) builds its own robust scenes whichever is asked."""

    def __init__(self, corners: np.ndarray, fast: bool = False) -> None:
        start = time.perf_counter()
        self.count = int(corners.shape[0])
        self._handle = 0
        self._scene = None  # the embreex fallback's scene
        self._embree = _embree()
        if self.count:
            corners = np.ascontiguousarray(corners, dtype=np.float32)
            if self._embree is not None:
                self._handle = self._embree.scene(corners, fast)
                # released when the scene object goes, or at exit: a finalizer holds what
                # it calls (a __del__ run at interpreter shutdown found ctypes torn down)
                self._release = weakref.finalize(self, self._embree.lib.rtcReleaseScene,
                                                 ctypes.c_void_p(self._handle))
            else:
                from embreex import rtcore_scene
                from embreex.mesh_construction import TriangleMesh

                self._scene = rtcore_scene.EmbreeScene()
                TriangleMesh(self._scene, corners)
                # embree commits lazily on the first query: force it, so build time is here
                self._scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32),
                                output=1)
        self.build_seconds = time.perf_counter() - start

    @property
    def handle(self) -> int:
        """The scene's Embree handle for the kernels (`intersect_range`); 0 when it is empty
        or the embreex binding traces it."""
        return self._handle

    def intersect(
        self, origins: np.ndarray, directions: np.ndarray, tfar: np.ndarray, threads: int = 1,
        out: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Nearest hit per ray: (t, primitive id (-1 on a miss), u, v), t = inf on a miss.

        u and v are the barycentric weights of corners 1 and 2. t is in units of the
        direction's length; rays start at their origin (tnear = 0) and stop at tfar.
        `out`: (n,) float32, int32, float32, float32 arrays the kernel fills instead of new
        ones (the tracer keeps them across frames; an empty scene returns its own misses).
        """
        n = origins.shape[0]
        if self.count == 0 or n == 0:
            return self._misses(n)
        origins = np.ascontiguousarray(origins, dtype=np.float32)
        directions = np.ascontiguousarray(directions, dtype=np.float32)
        tfar = np.ascontiguousarray(tfar, dtype=np.float32)
        if self._handle:
            if out is None:
                t = np.empty(n, np.float32)
                prim = np.empty(n, np.int32)
                u = np.empty(n, np.float32)
                v = np.empty(n, np.float32)
            else:
                t, prim, u, v = out
            # runs of 64 packets, in chunks of one (numba's OpenMP layer still gives each
            # thread a fixed share of them: see parallel.py)
            chunks = max(1, n // (64 * _LANES))
            with numba.parallel_chunksize(1):
                _intersect(self._handle, origins, directions, tfar, chunks, t, prim, u, v)
            return t, prim, u, v
        return self._intersect_embreex(origins, directions, tfar, threads)

    def _misses(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(inf, -1, 0, 0) for n rays: views of arrays kept by this (empty) scene, filled once
        (an empty scene is asked every bounce of every frame). Callers only read them."""
        kept = getattr(self, "_miss_arrays", None)
        if kept is None or kept[0].shape[0] < n:
            kept = (np.full(n, np.inf, np.float32), np.full(n, -1, np.int32),
                    np.zeros(n, np.float32), np.zeros(n, np.float32))
            self._miss_arrays = kept
        return tuple(a[:n] for a in kept)

    def _intersect_embreex(self, origins, directions, tfar, threads):
        n = origins.shape[0]
        t = np.full(n, np.inf, np.float32)
        prim = np.full(n, -1, np.int32)
        u = np.zeros(n, np.float32)
        v = np.zeros(n, np.float32)

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
