"""`rasterize`: world-space triangles to the triangle id and eye depth of every pixel."""

from __future__ import annotations

import numba
import numpy as np

from ...camera import standard_planes
from .buffers import RasterBuffers, RasterWorkspace, read_only, thread_buffers
from .constants import _CHUNK, _MAX_PLANES, CULL_NONE
from .draw import _draw
from .fixed import guarded_planes
from .resolve import _resolve
from .stencil import stencil_box


def rasterize(
    corners: np.ndarray,
    flags: np.ndarray,
    clip_from_world: np.ndarray,
    width: int,
    height: int,
    planes: np.ndarray | None = None,
    cull: int = CULL_NONE,
    mask: np.ndarray | None = None,
    depth_floor: np.ndarray | None = None,
    workspace: RasterWorkspace | None = None,
    clear_outside: bool = True,
) -> RasterBuffers:
    """Rasterize world-space triangles (T, 3, 3) with an OpenGL-style world->clip matrix.

    `flags` per triangle: bit 0 (FLAG_MIRROR, or a bool array) marks mirrors, which win
    depth ties; bit 1 (FLAG_SKIP) leaves the triangle out of this pass; bit 2
    (FLAG_CULL_BACK) drops it when its screen winding is clockwise, bit 3 (FLAG_CULL_FRONT)
    when counter-clockwise, besides what `cull` drops.
    `planes` are clip-space half-spaces (P, 4), near and far first; default near + far.
    `cull`: CULL_BACK drops triangles whose screen winding is clockwise (seen from behind),
    CULL_FRONT the opposite (for a mirrored camera, whose handedness is flipped).
    `mask` (H, W) bool is a stencil: only its pixels are drawn, and only rows and columns
    of its bounding box are visited. `depth_floor` (H, W) eye-space depths: fragments at or
    in front of it are dropped (a second z-buffer, e.g. a curved reflector's own depth).
    `workspace`: scratch arrays to reuse (see RasterWorkspace).
    `clear_outside` False (a masked pass into a workspace's outputs, read only inside the
    stencil's box): the pixels outside that box keep what the last call left, not cleared
    (a 512^2 pass over a small reflector's box wrote the whole image: 2 MB a pass).
    """
    ws = workspace if workspace is not None else RasterWorkspace()
    if planes is None:
        planes = standard_planes()
    planes = np.asarray(planes, dtype=np.float64)
    assert planes.shape[0] <= _MAX_PLANES
    all_planes, bits = guarded_planes(planes, width, height)
    corners = np.ascontiguousarray(corners, dtype=np.float32)
    flags = read_only(flags)  # (one signature of the kernels: `read_only`)
    m = np.ascontiguousarray(clip_from_world, dtype=np.float64)
    if ws.outputs or ws.ids:  # (ids: the depth buffer alone fresh)
        tri = ws.get("tri", (height, width), np.int32)
        out = (ws.get("b1", (height, width), np.float32),
               ws.get("b2", (height, width), np.float32))
    else:
        tri = np.empty((height, width), np.int32)
        out = None
    depth = (ws.get("depth", (height, width), np.float32) if ws.outputs
             else np.empty((height, width), np.float32))
    if mask is None:
        stencil = ws.constant("stencil", (1, 1), np.uint8, 1)
        x0, x1, y0, y1 = 0, width, 0, height
    else:
        stencil = stencil_bytes(mask)
        x0, x1, y0, y1 = stencil_box(stencil)
    floor = (ws.constant("floor", (1, 1), np.float32, 0.0) if depth_floor is None
             else np.ascontiguousarray(depth_floor, dtype=np.float32))
    # sort-last: each thread draws whole triangles into its own buffers (the stencil's box),
    # merged per pixel at the end; the depth test prefers the lower triangle index on equal
    # keys, so the order triangles reach a buffer, and which buffer, never matter
    threads = max(1, numba.get_num_threads())
    box = (max(y1 - y0, 0), max(x1 - x0, 0))
    own_tri, own_key = thread_buffers(ws, threads, *box)
    drew = np.zeros(threads, np.bool_)  # which threads' buffers hold this call's drawing
    if box[0] > 0 and corners.shape[0] > 0:
        chunks = (corners.shape[0] + _CHUNK - 1) // _CHUNK
        # with a workspace, chunks whose box cannot reach the stencil's box are skipped,
        # by boxes kept with a scene's corners; not for corners in the workspace's own
        # buffers (rewritten every call: virtual's triangles), where making the boxes cost
        # more than they saved (virtual passes, 1 thread: four-spheres 4.0 -> 3.2 ms a
        # frame, mask 4.0 -> 3.7 ms; boxes made as each chunk is drawn: 3.6 and 4.0 ms)
        keep = workspace is not None and not ws.owns(corners)
        bounds = ws.chunk_bounds(corners) if keep else np.empty((0, 6))
        # chunks claimed one at a time by whichever thread is free (their work differs,
        # and on a busy machine a thread may lose its core)
        _draw(corners, flags, m, all_planes, planes.shape[0], width, height, bits, cull,
              chunks, bounds, stencil, mask is not None, floor, depth_floor is not None,
              x0, x1, y0, y1, own_tri, own_key, drew)
    else:
        own_tri = ws.get("own_tri", (0, *box), np.int32)
        own_key = ws.get("own_key", (0, *box), np.float32)
    _resolve(flags, x0, x1, y0, y1, own_tri, own_key, drew, tri, depth,
             clear_outside or mask is None)
    return RasterBuffers(tri, None, None, depth, corners, m, out)


def stencil_bytes(mask: np.ndarray) -> np.ndarray:
    """`mask` (H, W) as the uint8 stencil the kernels read: a writable C-contiguous bool
    mask is viewed as its bytes (True is 1; the same values its uint8 copy held), not copied
    (an image-sized array a masked pass); anything else converted. (A read-only view would
    compile the kernels again: `read_only`.)"""
    if mask.dtype == np.bool_ and mask.flags.c_contiguous and mask.flags.writeable:
        return mask.view(np.uint8)
    return np.ascontiguousarray(mask, dtype=np.uint8)

