"""What a pass leaves (`RasterBuffers`) and the scratch kept from call to call
(`RasterWorkspace`)."""

from __future__ import annotations

import math

import numpy as np

from ..bounds import run_bounds
from .barycentrics import _barycentrics
from .constants import _CHUNK, _NARROW


class RasterBuffers:
    """What a pass left visible: per pixel the triangle id (int32, -1 where nothing was
    drawn), its barycentric weights of corners 1 and 2 (float32) and its eye-space depth
    (float32, +inf where nothing was drawn), all (H, W). A pass with `clear_outside=False`
    sets these only inside its stencil's box: outside it they are what the workspace held
    from an earlier pass (ids of other triangles), so its consumers read only the box.

    The rasterizer gives ids and depths; `b1` and `b2` are recovered from the triangles'
    clip-space corners on first use (`recover`), so a pass whose consumer recovers them
    itself (the shading kernels) never writes them."""

    def __init__(self, triangle: np.ndarray, b1: np.ndarray | None, b2: np.ndarray | None,
                 depth: np.ndarray, corners: np.ndarray | None = None,
                 clip_from_world: np.ndarray | None = None,
                 out: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        assert (b1 is None) == (b2 is None)
        assert b1 is not None or (corners is not None and clip_from_world is not None)
        self.triangle = triangle
        self.depth = depth
        self._b1, self._b2 = b1, b2
        self.corners = corners  # (T, 3, 3) world, float32: what `recover` reads
        self.clip_from_world = clip_from_world  # (4, 4) float64
        self._out = out

    @property
    def recover(self) -> bool:
        """True while b1 and b2 have not been made: a consumer may recover them itself."""
        return self._b1 is None

    def _barycentrics(self) -> None:
        h, w = self.triangle.shape
        if self._out is not None:
            b1, b2 = self._out
        else:
            b1, b2 = np.empty((h, w), np.float32), np.empty((h, w), np.float32)
        _barycentrics(self.triangle, self.corners, self.clip_from_world, b1, b2)
        self._b1, self._b2 = b1, b2

    @property
    def b1(self) -> np.ndarray:
        if self._b1 is None:
            self._barycentrics()
        return self._b1

    @property
    def b2(self) -> np.ndarray:
        if self._b2 is None:
            self._barycentrics()
        return self._b2


class RasterWorkspace:
    """Scratch arrays of `rasterize` kept from call to call (grown, never shrunk): fresh
    arrays of tens of megabytes a frame cost more in page faults than the work in them.
    With `outputs=True` the returned buffers are the workspace's too (valid until the next
    call): for passes whose buffers are consumed at once. With `ids=True` (and outputs
    False) the triangle ids and the recovered barycentrics are the workspace's (valid until
    the next call) while the depth buffer stays fresh: for a primary pass whose frame keeps
    its depth but whose ids and barycentrics are read only while the frame renders (ssr,
    ppr)."""

    def __init__(self, outputs: bool = False, ids: bool = False) -> None:
        self.outputs = outputs
        self.ids = ids
        self._arrays: dict[str, np.ndarray] = {}

    def get(self, name: str, shape: tuple[int, ...], dtype) -> np.ndarray:
        size = math.prod(shape)
        a = self._arrays.get(name)
        if a is None or a.dtype != np.dtype(dtype) or a.size < size:
            a = np.empty(max(size, 1), dtype)
            self._arrays[name] = a
        return a[:size].reshape(shape)

    def zeroed(self, name: str, shape: tuple[int, ...], dtype) -> np.ndarray:
        """`get`'s array, holding zeros: filled with them when made, or when its last user
        did not give it back zeroed (`given_back_zeroed`), so that a user who marks a few
        entries and clears just those need not clear the whole array each call."""
        size = math.prod(shape)
        a = self._arrays.get(name)
        zeroed = self._arrays.pop(f"{name}:zeroed", False)  # dirty until given back
        if a is None or a.dtype != np.dtype(dtype) or a.size < size:
            a = np.zeros(max(size, 1), dtype)
            self._arrays[name] = a
        elif not zeroed:
            a.fill(0)
        return a[:size].reshape(shape)

    def given_back_zeroed(self, name: str) -> None:
        """The caller of `zeroed(name, ...)` left every entry of it zero again."""
        self._arrays[f"{name}:zeroed"] = True

    def chunk_bounds(self, corners: np.ndarray) -> np.ndarray:
        """(chunks, 6) world-space boxes (min xyz, max xyz) of `corners` (T, 3, 3) in runs
        of _CHUNK triangles, kept while the same array comes back (a scene's geometry is
        built once; its arrays are not written after). Corners held in one of this
        workspace's own buffers (rewritten between calls) are never kept."""
        kept = self._arrays.get("bounds_of")
        if kept is not None and kept[0] is corners:
            return kept[1]
        chunks = (corners.shape[0] + _CHUNK - 1) // _CHUNK
        bounds = np.empty((chunks, 6))
        if chunks:
            run_bounds(corners, _CHUNK, bounds)
        if not self.owns(corners):
            self._arrays["bounds_of"] = (corners, bounds)
        return bounds

    def kept(self, name: str, source: object, key: tuple, make):
        """make()'s answer, kept while the same `source` object (a scene's geometry: built
        once, not written after) comes back with an equal `key`."""
        last = self._arrays.get(name)
        if last is not None and last[0] is source and last[1] == key:
            return last[2]
        answer = make()
        self._arrays[name] = (source, key, answer)
        return answer

    def owns(self, corners: np.ndarray) -> bool:
        """True for an array held in one of this workspace's own buffers (rewritten
        between calls: its run boxes cannot be kept)."""
        return any(corners.base is a for a in self._arrays.values())

    def constant(self, name: str, shape: tuple[int, int], dtype, value) -> np.ndarray:
        """A (H, W) array holding `value` (filled once; callers must not write it)."""
        key = f"{name}:{value}"
        a = self._arrays.get(key)
        if a is None or a.shape != shape:
            a = np.full(shape, value, dtype)
            self._arrays[key] = a
        return a


def scratch(ws: RasterWorkspace | None, name: str, shape: tuple[int, ...],
            dtype) -> np.ndarray:
    """An array of `shape` and `dtype`, contents undefined: the workspace's `name` (kept
    from call to call, so a frame's large arrays fault their pages in once) if a workspace
    is given, else a fresh one."""
    return np.empty(shape, dtype) if ws is None else ws.get(name, shape, dtype)


def thread_buffers(ws: RasterWorkspace, threads: int, rows: int,
                   cols: int) -> tuple[np.ndarray, np.ndarray]:
    """Each drawing thread's triangle ids and keys over a box of rows x cols (sort-last),
    with a spare row and _NARROW - 1 spare columns: `_rows` walks a row in whole blocks of
    _BLOCK pixels, `_narrow` in _NARROW (>= _BLOCK), `_quad` writes 2 x 2 pixels; those past
    the box are written back unchanged, never clamped."""
    padded = (max(rows, 0) + 1, max(cols, 0) + _NARROW - 1)
    return (ws.get("own_tri", (threads, *padded), np.int32),
            ws.get("own_key", (threads, *padded), np.float32))


def read_only(array: np.ndarray, dtype=np.uint8) -> np.ndarray:
    """`array` contiguous, of `dtype` (default: the rasterizer flags' uint8) and read-only
    (a view when it is writable), as kernels that also get kept read-only arrays take it:
    numba compiles a kernel again for each of a read-only and a writable array (a minute
    and a half for `_draw`, whose primary-pass flags are kept read-only: raster/closed.py)."""
    array = np.ascontiguousarray(array, dtype=dtype)
    if array.flags.writeable:
        array = array.view()
        array.flags.writeable = False
    return array
