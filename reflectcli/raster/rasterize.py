"""Z-buffer rasterization of triangles into triangle-id, barycentric and depth buffers.

Pipeline per triangle: world -> clip (one 4x4), clipping in homogeneous clip space against
the near and far planes and any extra planes (Sutherland-Hodgman, each clipped vertex carrying
its barycentrics in the original triangle), perspective divide to NDC, viewport to screen
(x right, y down, pixel centers at +0.5). Per pixel, screen-linear weights become
perspective-correct barycentrics through 1/w; the depth buffer holds eye-space depth w.

Determinism: one horizontal band of the screen per task, each band visiting the triangles in
index order with a strict less-than depth test, so the result is independent of the thread
count. A mirror's depth is scaled by MIRROR_TIE before the test (mirrors win ties).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numba import njit, prange

from ..camera import screen_from_ndc as _screen_from_ndc
from ..camera import standard_planes
from ..scene.types import MIRROR_TIE

_MAX_PLANES = 8
_MAX_POLY = 3 + _MAX_PLANES

# culling modes
CULL_NONE, CULL_BACK, CULL_FRONT = 0, 1, 2

# per-triangle flags
FLAG_MIRROR, FLAG_SKIP = 1, 2

# triangle status after setup
_CULLED, _SIMPLE, _CLIPPED = 0, 1, 2

screen_from_ndc = njit(cache=True, inline="always")(_screen_from_ndc)


@dataclass
class RasterBuffers:
    triangle: np.ndarray  # (H, W) int32, -1 where nothing was drawn
    b1: np.ndarray  # (H, W) float32, barycentric weight of corner 1
    b2: np.ndarray  # (H, W) float32, barycentric weight of corner 2
    depth: np.ndarray  # (H, W) float32, eye-space depth, +inf where nothing was drawn


class RasterWorkspace:
    """Scratch arrays of `rasterize` kept from call to call (grown, never shrunk): fresh
    arrays of tens of megabytes a frame cost more in page faults than the work in them.
    With `outputs=True` the returned buffers are the workspace's too (valid until the next
    call): for passes whose buffers are consumed at once."""

    def __init__(self, outputs: bool = False) -> None:
        self.outputs = outputs
        self._arrays: dict[str, np.ndarray] = {}

    def get(self, name: str, shape: tuple[int, ...], dtype) -> np.ndarray:
        size = int(np.prod(shape))
        a = self._arrays.get(name)
        if a is None or a.dtype != np.dtype(dtype) or a.size < size:
            a = np.empty(max(size, 1), dtype)
            self._arrays[name] = a
        return a[:size].reshape(shape)

    def constant(self, name: str, shape: tuple[int, int], dtype, value) -> np.ndarray:
        """A (H, W) array holding `value` (filled once; callers must not write it)."""
        key = f"{name}:{value}"
        a = self._arrays.get(key)
        if a is None or a.shape != shape:
            a = np.full(shape, value, dtype)
            self._arrays[key] = a
        return a


def rasterize(
    corners: np.ndarray,
    flags: np.ndarray,
    world_to_clip: np.ndarray,
    width: int,
    height: int,
    planes: np.ndarray | None = None,
    cull: int = CULL_NONE,
    mask: np.ndarray | None = None,
    depth_floor: np.ndarray | None = None,
    workspace: RasterWorkspace | None = None,
) -> RasterBuffers:
    """Rasterize world-space triangles (T, 3, 3) with an OpenGL-style world->clip matrix.

    `flags` per triangle: bit 0 (FLAG_MIRROR, or a bool array) marks mirrors, which win
    depth ties; bit 1 (FLAG_SKIP) leaves the triangle out of this pass.
    `planes` are clip-space half-spaces (P, 4), near and far first; default near + far.
    `cull`: CULL_BACK drops triangles whose screen winding is clockwise (seen from behind),
    CULL_FRONT the opposite (for a mirrored camera, whose handedness is flipped).
    `mask` (H, W) bool is a stencil: only its pixels are drawn, and only rows and columns
    of its bounding box are visited. `depth_floor` (H, W) eye-space depths: fragments at or
    in front of it are dropped (a second z-buffer, e.g. a curved reflector's own depth).
    `workspace`: scratch arrays to reuse (see RasterWorkspace).
    """
    ws = workspace if workspace is not None else RasterWorkspace()
    if planes is None:
        planes = standard_planes()
    planes = np.ascontiguousarray(planes, dtype=np.float64)
    assert planes.shape[0] <= _MAX_PLANES
    corners = np.ascontiguousarray(corners, dtype=np.float32)
    flags = np.ascontiguousarray(flags, dtype=np.uint8)
    m = np.ascontiguousarray(world_to_clip, dtype=np.float64)
    t = corners.shape[0]
    screen = ws.get("screen", (t, 9), np.float64)
    status = ws.get("status", (t,), np.uint8)
    rows = ws.get("rows", (t, 2), np.int64)
    _setup(corners, m, planes, width, height, cull, screen, status, rows)
    if ws.outputs:
        tri = ws.get("tri", (height, width), np.int32)
        b1 = ws.get("b1", (height, width), np.float32)
        b2 = ws.get("b2", (height, width), np.float32)
        depth = ws.get("depth", (height, width), np.float32)
        _clear(tri, b1, b2, depth)
    else:
        tri = np.full((height, width), -1, np.int32)
        b1 = np.zeros((height, width), np.float32)
        b2 = np.zeros((height, width), np.float32)
        depth = np.full((height, width), np.inf, np.float32)
    if mask is None:
        stencil = ws.constant("stencil", (height, width), np.uint8, 1)
        x0, x1, y0, y1 = 0, width, 0, height
    else:
        stencil = np.ascontiguousarray(mask, dtype=np.uint8)
        ys = np.flatnonzero(stencil.any(axis=1))
        xs = np.flatnonzero(stencil.any(axis=0))
        if ys.size == 0:
            return RasterBuffers(tri, b1, b2, depth)
        x0, x1, y0, y1 = int(xs[0]), int(xs[-1]) + 1, int(ys[0]), int(ys[-1]) + 1
    floor = (ws.constant("floor", (height, width), np.float32, 0.0) if depth_floor is None
             else np.ascontiguousarray(depth_floor, dtype=np.float32))
    bands = min(y1 - y0, max(1, numba.get_num_threads()) * 8)
    chunks = max(1, numba.get_num_threads()) * 4
    counts = ws.get("counts", (chunks, bands), np.int64)
    _bin_count(status, flags, rows, y0, y1, bands, counts)
    offsets = ws.get("offsets", (bands + 1,), np.int64)
    starts = ws.get("starts", (chunks, bands), np.int64)
    total = _bin_starts(counts, offsets, starts)
    items = ws.get("items", (total,), np.int32)
    _bin_fill(status, flags, rows, y0, y1, bands, starts, items)
    # bands handed out one at a time to whichever thread is free (their work differs, and on
    # a busy machine a thread may lose its core); each band owns its rows: same result
    with numba.parallel_chunksize(1):
        _draw(corners, flags, m, planes, width, height, cull, screen, status, bands, offsets,
              items, stencil, floor, x0, x1, y0, y1, tri, b1, b2, depth)
    return RasterBuffers(tri, b1, b2, depth)


_CHUNK = 1024  # triangles per parallel task in setup (one scratch allocation per task)


@njit(cache=True, parallel=True)
def _setup(corners, m, planes, width, height, cull, screen, status, rows):
    """Per triangle: clip-space transform, trivial reject, and screen positions if unclipped.

    screen[t] = (x0, y0, 1/w0, x1, y1, 1/w1, x2, y2, 1/w2) in screen space; rows[t] = the
    first and last pixel rows it may cover (all rows for triangles that need clipping).
    """
    n = corners.shape[0]
    for chunk in prange((n + _CHUNK - 1) // _CHUNK):
        c = np.empty((3, 4))
        for t in range(chunk * _CHUNK, min(n, (chunk + 1) * _CHUNK)):
            _setup_one(corners, t, m, planes, width, height, cull, screen, status, rows, c)


@njit(cache=True, inline="always")
def _setup_one(corners, t, m, planes, width, height, cull, screen, status, rows, c):
    for k in range(3):
        x, y, z = corners[t, k, 0], corners[t, k, 1], corners[t, k, 2]
        for r in range(4):
            c[k, r] = m[r, 0] * x + m[r, 1] * y + m[r, 2] * z + m[r, 3]
    status[t] = _SIMPLE
    rows[t, 0] = 0
    rows[t, 1] = height - 1
    # frustum side planes: reject only (no clipping needed against them)
    if (c[0, 0] < -c[0, 3] and c[1, 0] < -c[1, 3] and c[2, 0] < -c[2, 3]) or (
        c[0, 0] > c[0, 3] and c[1, 0] > c[1, 3] and c[2, 0] > c[2, 3]) or (
        c[0, 1] < -c[0, 3] and c[1, 1] < -c[1, 3] and c[2, 1] < -c[2, 3]) or (
        c[0, 1] > c[0, 3] and c[1, 1] > c[1, 3] and c[2, 1] > c[2, 3]
    ):
        status[t] = _CULLED
        return
    for p in range(planes.shape[0]):
        outside = 0
        for k in range(3):
            s = (planes[p, 0] * c[k, 0] + planes[p, 1] * c[k, 1]
                 + planes[p, 2] * c[k, 2] + planes[p, 3] * c[k, 3])
            if s < 0.0:
                outside += 1
        if outside == 3:
            status[t] = _CULLED
            return
        if outside > 0:
            status[t] = _CLIPPED
    if status[t] != _SIMPLE:
        return
    for k in range(3):
        iw = 1.0 / c[k, 3]
        screen[t, 3 * k], screen[t, 3 * k + 1] = screen_from_ndc(c[k, 0] * iw, c[k, 1] * iw,
                                                                  width, height)
        screen[t, 3 * k + 2] = iw
    ylo = min(screen[t, 1], screen[t, 4], screen[t, 7])
    yhi = max(screen[t, 1], screen[t, 4], screen[t, 7])
    # pixel row py is covered only if its center py + 0.5 lies in [ylo, yhi]
    rows[t, 0] = max(int(np.ceil(ylo - 0.5)), 0)
    rows[t, 1] = min(int(np.floor(yhi - 0.5)), height - 1)
    if rows[t, 0] > rows[t, 1]:
        status[t] = _CULLED
        return
    if cull != CULL_NONE:
        area = _area(screen[t, 0], screen[t, 1], screen[t, 3], screen[t, 4],
                     screen[t, 6], screen[t, 7])
        # screen y points down: a counter-clockwise (front) triangle has negative area here
        if (cull == CULL_BACK and area > 0.0) or (cull == CULL_FRONT and area < 0.0):
            status[t] = _CULLED


@njit(cache=True, inline="always")
def _band_range(t, status, flags, rows, top, bottom, band_of):
    """First and last band triangle t reaches (last < first if it is drawn in none)."""
    if status[t] == _CULLED or flags[t] & FLAG_SKIP:
        return 0, -1
    lo = max(rows[t, 0], top)
    hi = min(rows[t, 1], bottom - 1)
    if lo > hi:
        return 0, -1
    return band_of[lo - top], band_of[hi - top]


@njit(cache=True, parallel=True)
def _clear(tri, b1, b2, depth):
    for y in prange(tri.shape[0]):
        for x in range(tri.shape[1]):
            tri[y, x] = -1
            b1[y, x] = 0.0
            b2[y, x] = 0.0
            depth[y, x] = np.inf


@njit(cache=True, inline="always")
def _band_table(top, bottom, bands):
    span = bottom - top
    band_of = np.empty(span, np.int64)
    for b in range(bands):
        for y in range(top + b * span // bands, top + (b + 1) * span // bands):
            band_of[y - top] = b
    return band_of


@njit(cache=True, parallel=True)
def _bin_count(status, flags, rows, top, bottom, bands, counts):
    """counts[c, b]: triangles of chunk c (a contiguous range) that reach band b."""
    band_of = _band_table(top, bottom, bands)
    chunks = counts.shape[0]
    n = status.shape[0]
    for c in prange(chunks):
        for b in range(bands):
            counts[c, b] = 0
        for t in range(c * n // chunks, (c + 1) * n // chunks):
            first, last = _band_range(t, status, flags, rows, top, bottom, band_of)
            for b in range(first, last + 1):
                counts[c, b] += 1


@njit(cache=True)
def _bin_starts(counts, offsets, starts):
    """Band b's list is offsets[b]..offsets[b+1], chunk by chunk (so in triangle order);
    starts[c, b]: where chunk c writes its part. Returns the item count."""
    chunks, bands = counts.shape
    total = 0
    for b in range(bands):
        offsets[b] = total
        for c in range(chunks):
            starts[c, b] = total
            total += counts[c, b]
    offsets[bands] = total
    return total


@njit(cache=True, parallel=True)
def _bin_fill(status, flags, rows, top, bottom, bands, starts, items):
    band_of = _band_table(top, bottom, bands)
    chunks = starts.shape[0]
    n = status.shape[0]
    for c in prange(chunks):
        fill = starts[c].copy()
        for t in range(c * n // chunks, (c + 1) * n // chunks):
            first, last = _band_range(t, status, flags, rows, top, bottom, band_of)
            for b in range(first, last + 1):
                items[fill[b]] = t
                fill[b] += 1


@njit(cache=True, inline="always")
def _area(x0, y0, x1, y1, x2, y2):
    return (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)


@njit(cache=True)
def _clip_polygon(corners, t, m, planes, width, height, out_xyw, out_bary):
    """Clip triangle t against all planes; write screen (x, y, 1/w) and barycentrics.

    Returns the vertex count of the clipped convex polygon (0 if nothing is left).
    """
    poly = np.empty((_MAX_POLY, 7))  # clip x, y, z, w, then barycentrics b0, b1, b2
    nxt = np.empty((_MAX_POLY, 7))
    for k in range(3):
        x, y, z = corners[t, k, 0], corners[t, k, 1], corners[t, k, 2]
        for r in range(4):
            poly[k, r] = m[r, 0] * x + m[r, 1] * y + m[r, 2] * z + m[r, 3]
        for b in range(3):
            poly[k, 4 + b] = 1.0 if b == k else 0.0
    n = 3
    for p in range(planes.shape[0]):
        count = 0
        for i in range(n):
            j = (i + 1) % n
            si = (planes[p, 0] * poly[i, 0] + planes[p, 1] * poly[i, 1]
                  + planes[p, 2] * poly[i, 2] + planes[p, 3] * poly[i, 3])
            sj = (planes[p, 0] * poly[j, 0] + planes[p, 1] * poly[j, 1]
                  + planes[p, 2] * poly[j, 2] + planes[p, 3] * poly[j, 3])
            if si >= 0.0:
                for q in range(7):
                    nxt[count, q] = poly[i, q]
                count += 1
            if (si >= 0.0) != (sj >= 0.0):
                a = si / (si - sj)
                for q in range(7):
                    nxt[count, q] = poly[i, q] + a * (poly[j, q] - poly[i, q])
                count += 1
        n = count
        for i in range(n):
            for q in range(7):
                poly[i, q] = nxt[i, q]
        if n < 3:
            return 0
    for i in range(n):
        iw = 1.0 / poly[i, 3]
        out_xyw[i, 0], out_xyw[i, 1] = screen_from_ndc(poly[i, 0] * iw, poly[i, 1] * iw, width,
                                                       height)
        out_xyw[i, 2] = iw
        for b in range(3):
            out_bary[i, b] = poly[i, 4 + b]
    return n


_SPAN_MIN = 6  # bounding boxes at least this many pixels wide get a span per row


@njit(cache=True, inline="always")
def _row_span(xa, ya, xb, yb, sy, sgn, lo, hi):
    """Narrow the pixel columns [lo, hi] of row centre `sy` to those that can lie on the
    inner side of edge a -> b (sgn: the sign of the triangle's area), by a margin.

    The edge function _area(xa, ya, xb, yb, sx, sy) = c - (sx - xa) * d changes sign at
    sx = xa + c / d. The bound is widened by a pixel plus far more than the float64 rounding
    of the per-pixel test can move that crossing (a few ulps of the terms, over |d|), so the
    set of pixels the exact test accepts never changes; nearly horizontal edges (whose
    crossing is ill-conditioned) narrow nothing."""
    d = yb - ya
    c = (xb - xa) * (sy - ya)
    if abs(d) < 1e-6:
        return lo, hi
    root = xa + c / d  # the column where the edge function is zero
    slack = 1.0 + 1e-9 * (abs(c / d) + abs(xa) + abs(xb) + 1.0)
    if sgn * d > 0.0:  # inside: sx <= root
        edge = root - 0.5 + slack
        if edge < hi:
            hi = int(np.floor(edge)) if edge > lo - 1 else lo - 1
    else:  # inside: sx >= root
        edge = root - 0.5 - slack
        if edge > lo:
            lo = int(np.ceil(edge)) if edge < hi + 1 else hi + 1
    return lo, hi


@njit(cache=True)
def _fill(t, key_scale, x0, y0, w0, x1, y1, w1, x2, y2, w2, ba, bb, bc, row0, row1, col0, col1,
          stencil, floor, tri, b1, b2, depth):
    """Scan one screen triangle over rows [row0, row1) and columns [col0, col1), stencil on.

    ba/bb/bc: the corners' barycentrics in the original triangle (3,)."""
    area = _area(x0, y0, x1, y1, x2, y2)
    if area == 0.0:
        return
    inv_area = 1.0 / area
    xmin = max(int(np.floor(min(x0, x1, x2) - 0.5)), col0)
    xmax = min(int(np.ceil(max(x0, x1, x2) - 0.5)), col1 - 1)
    ymin = max(int(np.floor(min(y0, y1, y2) - 0.5)), row0)
    ymax = min(int(np.ceil(max(y0, y1, y2) - 0.5)), row1 - 1)
    sgn = 1.0 if area > 0.0 else -1.0
    wide = xmax - xmin >= _SPAN_MIN
    for py in range(ymin, ymax + 1):
        sy = py + 0.5
        lo, hi = xmin, xmax
        if wide:  # the row's span, widened: the exact test below still decides every pixel
            lo, hi = _row_span(x1, y1, x2, y2, sy, sgn, lo, hi)
            lo, hi = _row_span(x2, y2, x0, y0, sy, sgn, lo, hi)
            lo, hi = _row_span(x0, y0, x1, y1, sy, sgn, lo, hi)
        for px in range(lo, hi + 1):
            if stencil[py, px] == 0:
                continue
            sx = px + 0.5
            l0 = _area(x1, y1, x2, y2, sx, sy) * inv_area
            l1 = _area(x2, y2, x0, y0, sx, sy) * inv_area
            l2 = 1.0 - l0 - l1
            if l0 < 0.0 or l1 < 0.0 or l2 < 0.0:
                continue
            q0 = l0 * w0
            q1 = l1 * w1
            q2 = l2 * w2
            iw = q0 + q1 + q2
            w = 1.0 / iw
            key = w * key_scale
            if key < depth[py, px] and w > floor[py, px]:
                depth[py, px] = key
                tri[py, px] = t
                b1[py, px] = (q0 * ba[1] + q1 * bb[1] + q2 * bc[1]) * w
                b2[py, px] = (q0 * ba[2] + q1 * bb[2] + q2 * bc[2]) * w


@njit(cache=True, parallel=True)
def _draw(corners, flags, m, planes, width, height, cull, screen, status, bands, offsets, items,
          stencil, floor, col0, col1, top, bottom, tri, b1, b2, depth):
    e0 = np.array([1.0, 0.0, 0.0])
    e1 = np.array([0.0, 1.0, 0.0])
    e2 = np.array([0.0, 0.0, 1.0])
    rows = bottom - top
    for band in prange(bands):
        row0 = top + band * rows // bands
        row1 = top + (band + 1) * rows // bands
        xyw = np.empty((_MAX_POLY, 3))
        bary = np.empty((_MAX_POLY, 3))
        for item in range(offsets[band], offsets[band + 1]):
            t = items[item]
            st = status[t]
            key_scale = MIRROR_TIE if flags[t] & FLAG_MIRROR else 1.0
            if st == _SIMPLE:
                s = screen[t]
                _fill(t, key_scale, s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7], s[8],
                      e0, e1, e2, row0, row1, col0, col1, stencil, floor, tri, b1, b2, depth)
                continue
            n = _clip_polygon(corners, t, m, planes, width, height, xyw, bary)
            if n < 3:
                continue
            if cull != CULL_NONE:
                a = 0.0
                for i in range(1, n - 1):
                    a += _area(xyw[0, 0], xyw[0, 1], xyw[i, 0], xyw[i, 1],
                               xyw[i + 1, 0], xyw[i + 1, 1])
                if (cull == CULL_BACK and a > 0.0) or (cull == CULL_FRONT and a < 0.0):
                    continue
            for i in range(1, n - 1):
                _fill(t, key_scale, xyw[0, 0], xyw[0, 1], xyw[0, 2],
                      xyw[i, 0], xyw[i, 1], xyw[i, 2], xyw[i + 1, 0], xyw[i + 1, 1],
                      xyw[i + 1, 2], bary[0], bary[i], bary[i + 1], row0, row1, col0, col1,
                      stencil, floor, tri, b1, b2, depth)
    # depth keys of mirrors were scaled: undo so the buffer holds true eye-space depth
    for band in prange(bands):
        row0 = top + band * rows // bands
        row1 = top + (band + 1) * rows // bands
        for py in range(row0, row1):
            for px in range(col0, col1):
                t = tri[py, px]
                if t >= 0 and flags[t] & FLAG_MIRROR:
                    depth[py, px] = depth[py, px] / MIRROR_TIE
