"""Several masked passes drawn as one (`rasterize_passes`): each pass's triangles only on
its own label of a label stencil, inside its own box, in one parallel draw and one merge.
A virtual frame drew each sphere mirror's reflection as a pass of its own, two parallel
regions each; on two cores each region's start and join cost more than its work."""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

from ...camera import standard_planes
from ...parallel import claim, counter
from ...scene.types import MIRROR_TIE
from .buffers import RasterBuffers, RasterWorkspace, read_only, thread_buffers
from .constants import _CHUNK, _CLIPPED, _MAX_POLY, CULL_NONE, FLAG_MIRROR
from .draw import _draw_clipped, _fill_listed
from .fixed import guarded_planes
from .gather import gather_triangle
from .resolve import _resolve
from .setup import _run_setup, triangle_cull

MAX_PASSES = 255  # labels are uint8, 0 for no pass


def rasterize_passes(corners: np.ndarray, flags: np.ndarray, clip_from_world: np.ndarray,
                     width: int, height: int, starts: np.ndarray, boxes: np.ndarray,
                     labels: np.ndarray, depth_floor: np.ndarray | None,
                     workspace: RasterWorkspace, gather: tuple | None = None,
                     resolve: bool = True):
    """Passes p = 0 .. P - 1 at once: triangles starts[p] .. starts[p + 1] - 1 of `corners`
    (T, 3, 3 world, float32; `flags` as in rasterize) drawn where `labels` (H, W uint8)
    is p + 1, each clipped to its box boxes[p] (rows y0, y1, columns x0, x1, exclusive
    ends; holding every pixel of its label), near and far planes only, no culling.

    Every pixel of pass p gets exactly what `rasterize(corners[starts[p]:starts[p + 1]],
    ..., mask=labels == p + 1, clear_outside=False)` gives it (its ids offset by
    starts[p]): the same set-up clipped to the same box, the same tests. The buffers are
    the workspace's (outputs=True) and are set only inside the passes' common box; read
    them only on the labelled pixels.

    `gather` (points (N, 3) float32, hidden (N,) bool, corner_index (T, 3) int32, surface
    (T,), n_objects): the triangles as indices into shared points, `corners` and `flags`
    then the arrays to gather them into (`gather_triangle`) as each run is drawn: no pass
    of its own over the triangles, and no parallel region of its own. (Virtual's passes
    hand those dtypes: other ones compile the kernel again.)

    Returns the RasterBuffers; with `resolve` False, (buffers, pending): the threads'
    buffers are not merged here, and `pending` is what `shade_buffers(pending=...)` needs
    to merge each row as it shades it (the buffers' ids and depths inside the box are
    valid only after that)."""
    ws = workspace
    assert ws.outputs and boxes.shape[0] <= MAX_PASSES
    planes = standard_planes()
    all_planes, bits = guarded_planes(planes, width, height)
    # the kernels read the flags read-only (`read_only`: one signature for `_run_setup` and
    # `_resolve` with `rasterize`'s); the gather writes them through `written`, the same
    # memory
    if gather is None:
        corners = np.ascontiguousarray(corners, dtype=np.float32)
        flags = read_only(flags)
        written = np.zeros(1, np.uint8)  # never written: no gather
        points, hidden = np.zeros((1, 3), np.float32), np.zeros(1, np.bool_)
        corner_index, surface, n_objects = np.zeros((1, 3), np.int32), np.zeros(1, np.int32), 0
    else:
        points, hidden, corner_index, surface, n_objects = gather
        assert corners.dtype == np.float32 and flags.dtype == np.uint8
        assert corners.flags.c_contiguous and corners.shape[0] == corner_index.shape[0]
        assert flags.flags.c_contiguous and flags.flags.writeable
        written, flags = flags, read_only(flags)
    m = np.ascontiguousarray(clip_from_world, dtype=np.float64)
    tri = ws.get("tri", (height, width), np.int32)
    depth = ws.get("depth", (height, width), np.float32)
    out = (ws.get("b1", (height, width), np.float32), ws.get("b2", (height, width), np.float32))
    boxes = np.ascontiguousarray(boxes, np.int64)
    rows = boxes.tolist()  # a few numbers: Python's min and max beat numpy's reductions
    y0, y1 = min(r[0] for r in rows), max(r[1] for r in rows)
    x0, x1 = min(r[2] for r in rows), max(r[3] for r in rows)
    threads = max(1, numba.get_num_threads())
    own_tri, own_key = thread_buffers(ws, threads, y1 - y0, x1 - x0)
    drew = np.zeros(threads, np.bool_)
    floor = (ws.constant("floor", (1, 1), np.float32, 0.0) if depth_floor is None
             else np.ascontiguousarray(depth_floor, dtype=np.float32))
    _draw_passes(corners, flags, written, m, all_planes, planes.shape[0], width, height, bits,
                 np.ascontiguousarray(starts, np.int64), boxes,
                 np.ascontiguousarray(labels, np.uint8), floor, depth_floor is not None,
                 y0, x0, own_tri, own_key, drew, gather is not None, points, hidden,
                 corner_index, surface, n_objects)
    buffers = RasterBuffers(tri, None, None, depth, corners, m, out)
    if not resolve:
        return buffers, (flags, x0, x1, y0, y1, own_tri, own_key, drew, depth)
    _resolve(flags, x0, x1, y0, y1, own_tri, own_key, drew, tri, depth, False)
    return buffers


@njit(cache=True, parallel=True, error_model="numpy")
def _draw_passes(corners, flags, written, m, planes, n_cut, width, height, bits, starts, boxes,
                 labels, floor, use_floor, top, col0, own_tri, own_key, drew, gather, points,
                 hidden, corner_index, surface, n_objects):
    """`_draw` for several passes: runs of _CHUNK triangles within one pass (a run never
    spans two), claimed by whichever thread is free, each set up against its pass's box and
    filled where the label is its pass's, into per-thread buffers holding the passes'
    common box (corner top, col0). Who drew what never matters (see `_draw`). `gather`:
    each run's corners and flags are first gathered (`gather_triangle`) by the thread
    drawing it, the flags through `written` (writable; `flags`, read-only, is a view of
    the same memory, which the draw reads)."""
    passes = starts.shape[0] - 1
    first = np.empty(passes + 1, np.int64)  # each pass's first run (np.zeros: a parallel loop)
    first[0] = 0
    for p in range(passes):
        first[p + 1] = first[p] + (starts[p + 1] - starts[p] + _CHUNK - 1) // _CHUNK
    scale = float(1 << bits)
    threads = own_tri.shape[0]
    work_i = np.empty((threads, 22 * _CHUNK), np.int64)
    work_f = np.empty((threads, 8 * _CHUNK))
    status = np.empty((threads, _CHUNK), np.uint8)
    chosen = np.empty((threads, 4 * _CHUNK), np.int64)
    xyw = np.empty((threads, _MAX_POLY, 3))
    # as run-time values, not constants: `_run_setup` and `_draw_clipped` then take the
    # types `_draw` hands them (a constant compiled each a second time)
    cull = np.int64(CULL_NONE)
    use_stencil = np.bool_(True)
    claimed = counter()
    for me in prange(threads):
        p = 0
        while True:
            chunk = claim(claimed)
            if chunk >= first[passes]:
                break
            while chunk >= first[p + 1]:  # claims only grow: a worker's pass only advances
                p += 1
            row0, row1, c0, c1 = boxes[p, 0], boxes[p, 1], boxes[p, 2], boxes[p, 3]
            want = p + 1
            tri = own_tri[me]
            key = own_key[me]
            if not drew[me]:
                drew[me] = True
                for r in range(tri.shape[0]):
                    for c in range(tri.shape[1]):
                        tri[r, c] = -1
                        key[r, c] = 0.0
            t0 = starts[p] + (chunk - first[p]) * _CHUNK
            count = min(starts[p + 1], t0 + _CHUNK) - t0
            if gather:
                for t in range(t0, t0 + count):
                    gather_triangle(points, hidden, corner_index, surface, n_objects, corners,
                                    written, t)
            kept = _run_setup(corners, flags, m, planes, n_cut, width, height, bits, scale,
                              cull, row0, row1, c0, c1, t0, count,
                              work_i[me], work_f[me], status[me])
            ints = work_i[me]
            floats = work_f[me]
            st = status[me]
            sel = chosen[me]
            _fill_listed(ints, floats, sel, kept, t0, flags, top, col0, labels, True, floor,
                         use_floor, tri, key, want)
            clipped = 0
            for j in range(count):
                clipped += st[j] == _CLIPPED
            if clipped:
                for j in range(count):
                    if st[j] == _CLIPPED:
                        t = t0 + j
                        _draw_clipped(corners, t, 1.0 / MIRROR_TIE if flags[t] & FLAG_MIRROR
                                      else 1.0, m, planes, width, height, bits,
                                      triangle_cull(flags[t], cull), scale, xyw[me],
                                      row0, row1, c0, c1, labels, use_stencil, floor,
                                      use_floor, tri, key, top, col0, want)
