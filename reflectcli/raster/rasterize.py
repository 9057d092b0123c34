"""Z-buffer rasterization of triangles into triangle-id, depth and barycentric buffers.

Pipeline per triangle: world -> clip (one 4x4), clipping in homogeneous clip space against
the near and far planes, any extra planes and a guard band around the screen
(Sutherland-Hodgman), perspective divide to NDC, viewport to screen (x right, y down, pixel
centers at +0.5), then snapped to a fixed-point grid of 2^-S pixel (S = `_subpixel_bits`:
15 bits at 8192 pixels, 18 at 640x480, more on smaller screens).

Coverage is exact: the three edge functions of the snapped corners are int64 (no rounding),
stepped along each row, and a pixel center on an edge belongs to exactly one of the two
triangles sharing it (the top-left rule: an edge owns its points when its inward normal
points right, or straight down the screen). Shared edges leave neither cracks nor double
hits. The z-buffer holds the key 1/w (affine in screen space: a plane per triangle from its
bounding-box corner, float64, stored as float32; a mirror's divided by MIRROR_TIE, so mirrors
win ties); nearer is a greater key, and an equal key goes to the lower triangle index.
Barycentrics are not written per fragment: they are recovered from the visible triangle's
clip-space corners and the pixel center's NDC (`recover_barycentrics`: perspective-correct by
construction, the same for clipped triangles), by the shading kernels as they shade, or for
the whole buffer on first use of `RasterBuffers.b1` / `b2`. Eye depth is 1 / key.

Sort-last: triangles go in runs of _CHUNK, claimed by whichever thread is free
(parallel.py), each drawing into its own buffers (the stencil's box, plus _BLOCK - 1 spare
columns), merged per pixel at the end. The depth test and
the merge both pick the greatest key, then the lowest index, and every key depends only on
the triangle and the pixel, so the bytes are the same for any thread count and any order
the runs are drawn in. Within a run, the per-corner work (clip space, classification,
projection, snapping) is done for all its triangles at once in vectorised loops
(`_run_setup`), then each triangle is filled. With a workspace, a run whose world box
misses the view, an extra plane or the stencil's box is skipped whole (`_box_misses`).
"""
from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

from ..camera import screen_from_ndc as _screen_from_ndc
from ..camera import standard_planes
from ..parallel import claim
from ..scene.types import MIRROR_TIE
from .bounds import run_bounds

_MAX_PLANES = 8
_GUARD_PLANES = 4
_MAX_POLY = 3 + _MAX_PLANES + _GUARD_PLANES

# culling modes
CULL_NONE, CULL_BACK, CULL_FRONT = 0, 1, 2

# per-triangle flags
FLAG_MIRROR, FLAG_SKIP = 1, 2

# triangle status after setup
_CULLED, _SIMPLE, _CLIPPED = 0, 1, 2

# fixed-point corners stay within +-2^_FIXED_BITS: edge functions (products of two corner
# differences, summed) then stay below 2^62 in int64
_FIXED_BITS = 29

screen_from_ndc = njit(cache=True, inline="always")(_screen_from_ndc)


def _subpixel_bits(width: int, height: int) -> tuple[int, float]:
    """(S, guard): corners are snapped to 2^-S pixel and kept (by clipping) within `guard`
    pixels beyond each side of the screen, so every snapped coordinate is below
    2^_FIXED_BITS in magnitude."""
    span = 1 << int(np.ceil(np.log2(2 * max(width, height, 2))))  # >= 2 * the screen
    bits = _FIXED_BITS - int(np.log2(span))
    return bits, 0.45 * span


class RasterBuffers:
    """What a pass left visible: per pixel the triangle id (int32, -1 where nothing was
    drawn), its barycentric weights of corners 1 and 2 (float32) and its eye-space depth
    (float32, +inf where nothing was drawn), all (H, W).

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
        if not any(corners.base is a for a in self._arrays.values()):
            self._arrays["bounds_of"] = (corners, bounds)
        return bounds

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
    planes = np.asarray(planes, dtype=np.float64)
    assert planes.shape[0] <= _MAX_PLANES
    bits, guard = _subpixel_bits(width, height)
    gx, gy = 1.0 + 2.0 * guard / width, 1.0 + 2.0 * guard / height
    # the guard band: x_ndc in [-gx, gx], y_ndc in [-gy, gy] (clip x + gx w >= 0, ...)
    guard_planes = np.array([[1.0, 0, 0, gx], [-1.0, 0, 0, gx], [0, 1.0, 0, gy],
                             [0, -1.0, 0, gy]])
    all_planes = np.ascontiguousarray(np.vstack([planes, guard_planes]))
    corners = np.ascontiguousarray(corners, dtype=np.float32)
    flags = np.ascontiguousarray(flags, dtype=np.uint8)
    m = np.ascontiguousarray(world_to_clip, dtype=np.float64)
    if ws.outputs:
        tri = ws.get("tri", (height, width), np.int32)
        depth = ws.get("depth", (height, width), np.float32)
        out = (ws.get("b1", (height, width), np.float32),
               ws.get("b2", (height, width), np.float32))
    else:
        tri = np.empty((height, width), np.int32)
        depth = np.empty((height, width), np.float32)
        out = None
    if mask is None:
        stencil = ws.constant("stencil", (1, 1), np.uint8, 1)
        x0, x1, y0, y1 = 0, width, 0, height
    else:
        stencil = np.ascontiguousarray(mask, dtype=np.uint8)
        ys = np.flatnonzero(stencil.any(axis=1))
        xs = np.flatnonzero(stencil.any(axis=0))
        if ys.size == 0:
            x0 = x1 = y0 = y1 = 0
        else:
            x0, x1, y0, y1 = int(xs[0]), int(xs[-1]) + 1, int(ys[0]), int(ys[-1]) + 1
    floor = (ws.constant("floor", (1, 1), np.float32, 0.0) if depth_floor is None
             else np.ascontiguousarray(depth_floor, dtype=np.float32))
    # sort-last: each thread draws whole triangles into its own buffers (the stencil's box),
    # merged per pixel at the end; the depth test prefers the lower triangle index on equal
    # keys, so the order triangles reach a buffer, and which buffer, never matter
    threads = max(1, numba.get_num_threads())
    box = (max(y1 - y0, 0), max(x1 - x0, 0))
    # _BLOCK - 1 columns to spare: `_rows` walks a row in whole blocks of _BLOCK pixels
    padded = (box[0], box[1] + _BLOCK - 1)
    own_tri = ws.get("own_tri", (threads, *padded), np.int32)
    own_key = ws.get("own_key", (threads, *padded), np.float32)
    drew = np.zeros(threads, np.bool_)  # which threads' buffers hold this call's drawing
    if box[0] > 0 and corners.shape[0] > 0:
        chunks = (corners.shape[0] + _CHUNK - 1) // _CHUNK
        # with a workspace, chunks whose box cannot reach the stencil's box are skipped
        bounds = (ws.chunk_bounds(corners) if workspace is not None
                  else np.empty((0, 6)))
        # chunks claimed one at a time by whichever thread is free (their work differs,
        # and on a busy machine a thread may lose its core)
        _draw(corners, flags, m, all_planes, planes.shape[0], width, height, bits, cull,
              chunks, bounds, stencil, mask is not None, floor, depth_floor is not None,
              x0, x1, y0, y1, own_tri, own_key, drew)
    else:
        own_tri = ws.get("own_tri", (0, *box), np.int32)
        own_key = ws.get("own_key", (0, *box), np.float32)
    _resolve(flags, x0, x1, y0, y1, own_tri, own_key, drew, tri, depth)
    return RasterBuffers(tri, None, None, depth, corners, m, out)


_CHUNK = 256  # triangles per parallel task (and per box of chunk_bounds)
# A plain row is walked in whole blocks of _BLOCK pixels, those past the triangle's box
# masked (rewritten unchanged): the compiler's vectorised loop then never falls to its
# scalar remainder, whose branches on the row's length (1 to 4 pixels on most triangles of
# a detailed mesh) mispredict. 202k triangles, 1 thread: culled 1.03 -> 0.95x the anchor,
# unculled 1.41 -> 1.26x (8 was slower than 4)
_BLOCK = 4


@njit(cache=True, inline="always")
def _snap(v, scale):
    """A screen coordinate in units of 1/scale pixel, rounded to nearest (halves up)."""
    return np.int64(np.floor(v * scale + 0.5))


@njit(cache=True, inline="always")
def _clip_xyzw(m, x, y, z):
    x, y, z = np.float64(x), np.float64(y), np.float64(z)
    return (m[0, 0] * x + m[0, 1] * y + m[0, 2] * z + m[0, 3],
            m[1, 0] * x + m[1, 1] * y + m[1, 2] * z + m[1, 3],
            m[2, 0] * x + m[2, 1] * y + m[2, 2] * z + m[2, 3],
            m[3, 0] * x + m[3, 1] * y + m[3, 2] * z + m[3, 3])


@njit(cache=True, inline="always")
def _outside(planes, p, x, y, z, w):
    return planes[p, 0] * x + planes[p, 1] * y + planes[p, 2] * z + planes[p, 3] * w < 0.0


@njit(cache=True)
def _clip_polygon(corners, t, m, planes, width, height, out_xyw):
    """Clip triangle t against all planes; write its screen (x, y, 1/w) corners.

    Returns the vertex count of the clipped convex polygon (0 if nothing is left).
    """
    poly = np.empty((_MAX_POLY, 4))  # clip x, y, z, w
    nxt = np.empty((_MAX_POLY, 4))
    for k in range(3):
        x, y, z = corners[t, k, 0], corners[t, k, 1], corners[t, k, 2]
        for r in range(4):
            poly[k, r] = m[r, 0] * x + m[r, 1] * y + m[r, 2] * z + m[r, 3]
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
                for q in range(4):
                    nxt[count, q] = poly[i, q]
                count += 1
            if (si >= 0.0) != (sj >= 0.0):
                a = si / (si - sj)
                for q in range(4):
                    nxt[count, q] = poly[i, q] + a * (poly[j, q] - poly[i, q])
                count += 1
        n = count
        for i in range(n):
            for q in range(4):
                poly[i, q] = nxt[i, q]
        if n < 3:
            return 0
    for i in range(n):
        iw = 1.0 / poly[i, 3]
        out_xyw[i, 0], out_xyw[i, 1] = screen_from_ndc(poly[i, 0] * iw, poly[i, 1] * iw, width,
                                                       height)
        out_xyw[i, 2] = iw
    return n


@njit(cache=True, inline="always")
def _setup(x0, y0, w0, x1, y1, w1, x2, y2, w2, key_scale, cull, bits, top, bottom, col0, col1):
    """Triangle setup of one snapped screen triangle (corners in units of 2^-bits pixel,
    int64; w0..w2 their 1/w) for `_rows`, written without branches (a run's setups are one
    vectorised loop). Returns (drawn, xs, n, ys, ye, first_y, e0, e1, e2, sa0, sa1, sa2, sb0,
    sb1, sb2, z_ref, dzdx, dzdy, zx0): drawn is False for a culled or degenerate triangle,
    one whose pixel centers all miss the box [top, bottom) x [col0, col1), or one whose
    corners' box holds at most 2 x 2 centers, none inside; the edge functions at the center
    of pixel (xs, ys) with their biases, their steps along a row and down a column; the key
    plane as `_rows` evaluates it (meaningless where drawn is False)."""
    area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    # screen y points down: a counter-clockwise (front) triangle has negative area here
    facing = ((area != 0) & ((cull != CULL_BACK) | (area < 0))
              & ((cull != CULL_FRONT) | (area > 0)))
    # wind every triangle one way: inside is then where all edges are >= 0
    flip = area < 0
    x1, x2 = (x2, x1) if flip else (x1, x2)
    y1, y2 = (y2, y1) if flip else (y1, y2)
    w1, w2 = (w2, w1) if flip else (w1, w2)
    area = -area if flip else area
    one = np.int64(1)
    half = one << (bits - 1)
    first_x = -((half - min(x0, x1, x2)) >> bits)  # pixel centers inside the corners' box
    last_x = (max(x0, x1, x2) - half) >> bits
    first_y = -((half - min(y0, y1, y2)) >> bits)
    last_y = (max(y0, y1, y2) - half) >> bits
    xs = max(first_x, col0)
    xe = min(last_x, col1 - 1)
    ys = max(first_y, top)
    ye = min(last_y, bottom - 1)
    # edge k is opposite corner k: e_k(P) = a_k (Px - xa) + b_k (Py - ya) over edge a -> b
    a0, b0 = y1 - y2, x2 - x1
    a1, b1 = y2 - y0, x0 - x2
    a2, b2 = y0 - y1, x1 - x0
    # top-left rule: an edge owns the centers on it when its inward normal (a, b) points
    # right, or straight down; elsewhere a center must be strictly inside (e >= 1)
    bias0 = np.int64(0) if (a0 > 0) | ((a0 == 0) & (b0 > 0)) else np.int64(-1)
    bias1 = np.int64(0) if (a1 > 0) | ((a1 == 0) & (b1 > 0)) else np.int64(-1)
    bias2 = np.int64(0) if (a2 > 0) | ((a2 == 0) & (b2 > 0)) else np.int64(-1)
    px0 = (xs << bits) + half
    py0 = (ys << bits) + half
    e0 = a0 * (px0 - x1) + b0 * (py0 - y1) + bias0
    e1 = a1 * (px0 - x2) + b1 * (py0 - y2) + bias1
    e2 = a2 * (px0 - x0) + b2 * (py0 - y0) + bias2
    sa0, sa1, sa2 = a0 << bits, a1 << bits, a2 << bits
    sb0, sb1, sb2 = b0 << bits, b1 << bits, b2 << bits
    # a box of at most 2 x 2 centers (most small triangles) is tested here whole
    wide, tall = xe > xs, ye > ys
    covered = (((xe - xs) > 1) | ((ye - ys) > 1) | ((e0 | e1 | e2) >= 0)
               | (wide & (((e0 + sa0) | (e1 + sa1) | (e2 + sa2)) >= 0))
               | (tall & (((e0 + sb0) | (e1 + sb1) | (e2 + sb2)) >= 0))
               | (wide & tall & (((e0 + sa0 + sb0) | (e1 + sa1 + sb1)
                                  | (e2 + sa2 + sb2)) >= 0)))
    drawn = facing & (xs <= xe) & (ys <= ye) & covered
    # 1/w is affine in screen space: the plane through the corners, stepped from the
    # (unclamped) box corner, so a pixel's key depends on the triangle and pixel only
    # (a degenerate triangle is never drawn; dividing by 1 keeps the interpreted twin run
    # of this branch-free code, under NUMBA_DISABLE_JIT, from raising)
    inv_area = key_scale / float(area + (area == 0))
    sx = float(one << bits)
    dzdx = (a0 * w0 + a1 * w1 + a2 * w2) * sx * inv_area
    dzdy = (b0 * w0 + b1 * w1 + b2 * w2) * sx * inv_area
    cx = (first_x << bits) + half
    cy = (first_y << bits) + half
    z_ref = ((a0 * (cx - x1) + b0 * (cy - y1)) * w0 + (a1 * (cx - x2) + b1 * (cy - y2)) * w1
             + (a2 * (cx - x0) + b2 * (cy - y0)) * w2) * inv_area
    return (drawn, xs, xe - xs + 1, ys, ye, first_y, e0, e1, e2, sa0, sa1, sa2, sb0, sb1,
            sb2, z_ref, dzdx, dzdy, dzdx * (xs - first_x))


@njit(cache=True, inline="always")
def _rows(t32, xs, n, ys, ye, first_y, e0, e1, e2, sa0, sa1, sa2, sb0, sb1, sb2, z_ref,
          dzdx, dzdy, zx0, tie, top, col0, stencil, use_stencil, floor, use_floor, tri, key,
          blocks):
    """Draw the pixels of rows ys..ye, columns xs..xs+n-1 whose centers are inside (every
    edge function >= 0) into the box buffers (pixel (py, px) at [py - top, px - col0]).

    `blocks`: the buffers have _BLOCK - 1 columns to spare past the box, so a plain row is
    walked in whole blocks of _BLOCK. A row's pixels are read through views starting at
    column xs, indexed from 0: indexed [r, xs - col0 + k], numba's negative-index
    wraparound kept the plain loop scalar (with spills); this way it vectorises."""
    plain = not use_stencil and not use_floor
    c = xs - col0
    n4 = (n + _BLOCK - 1) & -_BLOCK if blocks else n
    for py in range(ys, ye + 1):
        z_row = z_ref + dzdy * (py - first_y) + zx0
        r = py - top
        f0, f1, f2 = e0, e1, e2
        if plain:  # without branches (a mispredicted one costs more than a pixel)
            # a view from column xs, indexed from 0: no wraparound, so it vectorises
            key_row = key[r, c:c + n4]
            tri_row = tri[r, c:c + n4]
            for k in range(n4):
                z = np.float32(z_row + dzdx * k)
                old = key_row[k]
                was = tri_row[k]
                win = (((f0 | f1 | f2) >= 0) & (k < n)
                       & ((z > old) | ((z == old) & (t32 < was))))
                key_row[k] = z if win else old
                tri_row[k] = t32 if win else was
                f0 += sa0
                f1 += sa1
                f2 += sa2
            e0 += sb0
            e1 += sb1
            e2 += sb2
            continue
        for k in range(n):
            if (f0 | f1 | f2) >= 0:
                zf = z_row + dzdx * k
                z = np.float32(zf)
                old = key[r, c + k]
                if (z > old or (z == old and t32 < tri[r, c + k])) and (
                        plain or ((not use_stencil or stencil[py, xs + k] != 0)
                                  and (not use_floor or zf * tie * floor[py, xs + k] < 1.0))):
                    key[r, c + k] = z
                    tri[r, c + k] = t32
            f0 += sa0
            f1 += sa1
            f2 += sa2
        e0 += sb0
        e1 += sb1
        e2 += sb2


@njit(cache=True, error_model="numpy")
def _fill(t, key_scale, cull, x0, y0, w0, x1, y1, w1, x2, y2, w2, bits, top, bottom, col0,
          col1, stencil, use_stencil, floor, use_floor, tri, key):
    """Draw one snapped screen triangle into the box [top, bottom) x [col0, col1) (`tri`
    and `key` hold the box: pixel (py, px) at [py - top, px - col0]): `_setup` then `_rows`.

    (x, y): corners in units of 2^-bits pixel (int64); w0..w2 their 1/w. A pixel is drawn
    where its center is inside (top-left rule), its stencil is set (`use_stencil`), its
    depth w is beyond floor's (`use_floor`), and its key 1/w * key_scale is greater than
    the stored one, or equal to it with a lower triangle index. `cull` as in rasterize."""
    s = _setup(np.int64(x0), np.int64(y0), np.float64(w0), np.int64(x1), np.int64(y1),
               np.float64(w1), np.int64(x2), np.int64(y2), np.float64(w2),
               np.float64(key_scale), cull, bits, top, bottom, col0, col1)
    if not s[0]:
        return
    _rows(np.int32(t), s[1], s[2], s[3], s[4], s[5], s[6], s[7], s[8], s[9], s[10], s[11],
          s[12], s[13], s[14], s[15], s[16], s[17], s[18], 1.0 / key_scale, top, col0,
          stencil, use_stencil, floor, use_floor, tri, key,
          key.shape[1] >= col1 - col0 + _BLOCK - 1)


@njit(cache=True, error_model="numpy")
def _box_misses(bounds, chunk, m, planes, n_cut, width, height, col0, col1, top, bottom):
    """True if no triangle inside the world box bounds[chunk] can cover a pixel center of
    [top, bottom) x [col0, col1): its 8 corners all outside one side of the frustum or one
    of the first n_cut planes (a half-space is convex), or all in front of the eye (w > 0)
    and projecting, with a pixel to spare, beside the box (the projection of a convex set
    in front of the eye lies in the hull of its corners' projections)."""
    out = np.zeros(4 + n_cut, np.int64)
    in_front = True
    lo_x = lo_y = np.inf
    hi_x = hi_y = -np.inf
    for k in range(8):
        x = bounds[chunk, 3 if k & 1 else 0]
        y = bounds[chunk, 4 if k & 2 else 1]
        z = bounds[chunk, 5 if k & 4 else 2]
        cx, cy, cz, cw = _clip_xyzw(m, x, y, z)
        out[0] += cx < -cw
        out[1] += cx > cw
        out[2] += cy < -cw
        out[3] += cy > cw
        for p in range(n_cut):
            out[4 + p] += _outside(planes, p, cx, cy, cz, cw)
        if cw > 0.0:
            sx, sy = screen_from_ndc(cx / cw, cy / cw, width, height)
            lo_x, hi_x = min(lo_x, sx), max(hi_x, sx)
            lo_y, hi_y = min(lo_y, sy), max(hi_y, sy)
        else:
            in_front = False
    for q in range(4 + n_cut):
        if out[q] == 8:
            return True
    return in_front and (hi_x < col0 - 1.0 or lo_x > col1 + 1.0 or hi_y < top - 1.0
                         or lo_y > bottom + 1.0)


@njit(cache=True, parallel=True, error_model="numpy")
def _draw(corners, flags, m, planes, n_cut, width, height, bits, cull, chunks, bounds, stencil,
          use_stencil, floor, use_floor, col0, col1, top, bottom, own_tri, own_key, drew):
    """Every triangle, in chunks of _CHUNK, into the buffers of the thread drawing it;
    chunks whose world box (`bounds`, if given) misses the view or the box are skipped. A
    thread clears its buffers before its first chunk and marks them in `drew` (one parallel
    region less: on a busy machine each costs a wake-up of the other threads).

    A chunk goes in two phases: `_run_setup` (clip space, classification, projection and
    snapping: loops without branches over the run, which the compiler vectorises, into
    small per-thread arrays), then per triangle `_fill` (culling, box, edge functions, key
    plane, pixels) or `_draw_clipped`."""
    n = corners.shape[0]
    scale = float(1 << bits)
    threads = own_tri.shape[0]
    soa = np.empty((threads, 9, _CHUNK), np.float32)
    clip = np.empty((threads, 12, _CHUNK))
    work_i = np.empty((threads, 21 * _CHUNK), np.int64)
    work_f = np.empty((threads, 7 * _CHUNK))
    status = np.empty((threads, _CHUNK), np.uint8)
    chosen = np.empty((threads, _CHUNK), np.int64)
    xyw = np.empty((threads, _MAX_POLY, 3))
    # one item per thread, each claiming the next chunk until none is left (parallel.py);
    # a worker draws into its own buffers, merged by key: who drew what never matters
    claimed = np.zeros(1, np.int64)
    for me in prange(threads):
        while True:
            chunk = claim(claimed)
            if chunk >= chunks:
                break
            if bounds.shape[0] > 0 and _box_misses(bounds, chunk, m, planes, n_cut, width,
                                                    height, col0, col1, top, bottom):
                continue
            tri = own_tri[me]
            key = own_key[me]
            if not drew[me]:
                drew[me] = True
                for r in range(tri.shape[0]):
                    for c in range(tri.shape[1]):
                        tri[r, c] = -1
                        key[r, c] = 0.0
            t0 = chunk * _CHUNK
            count = min(n, t0 + _CHUNK) - t0
            _run_setup(corners, flags, m, planes, n_cut, width, height, bits, scale, cull, top,
                       bottom, col0, col1, t0, count, soa[me], clip[me], work_i[me], work_f[me],
                       status[me])
            ints = work_i[me]
            floats = work_f[me]
            st = status[me]
            sel = chosen[me]
            c = _CHUNK
            # the triangles to fill, listed without a branch per triangle
            k = 0
            clipped = 0
            for j in range(count):
                sel[k] = j
                k += ints[20 * c + j]
                clipped += st[j] == _CLIPPED
            for i in range(k):
                j = sel[i]
                t = t0 + j
                _rows(np.int32(t), ints[6 * c + j], ints[7 * c + j], ints[8 * c + j],
                      ints[9 * c + j], ints[10 * c + j], ints[11 * c + j], ints[12 * c + j],
                      ints[13 * c + j], ints[14 * c + j], ints[15 * c + j], ints[16 * c + j],
                      ints[17 * c + j], ints[18 * c + j], ints[19 * c + j], floats[3 * c + j],
                      floats[4 * c + j], floats[5 * c + j], floats[6 * c + j],
                      MIRROR_TIE if flags[t] & FLAG_MIRROR else 1.0, top, col0, stencil,
                      use_stencil, floor, use_floor, tri, key, True)
            if clipped:
                for j in range(count):
                    if st[j] == _CLIPPED:
                        t = t0 + j
                        _draw_clipped(corners, t, 1.0 / MIRROR_TIE if flags[t] & FLAG_MIRROR
                                      else 1.0, m, planes, width, height, bits, cull, scale,
                                      xyw[me], top, bottom, col0, col1, stencil, use_stencil,
                                      floor, use_floor, tri, key)


@njit(cache=True, error_model="numpy")
def _run_setup(corners, flags, m, planes, n_cut, width, height, bits, scale, cull, top,
               bottom, col0, col1, t0, count, soa, clip, ints, floats, status):
    """Setup of triangles t0 .. t0 + count - 1 (j = t - t0), in loops over the run without
    branches (vectorised): their corners' clip coordinates, status[j] _CULLED (outside one
    side of the frustum or one of the first n_cut planes, or FLAG_SKIP), _CLIPPED (a plane
    cuts it, or it leaves the guard band) or _SIMPLE, and for a simple one its corners'
    snapped screen x, y (`snapped` rows 2k, 2k + 1) and 1/w (`inv_w` row k), the very
    values (same operations, same order) as a scalar loop per triangle would give.
    `soa`, `clip`: scratch, (9, n) corners and (12, n) clip x, y, z, w per corner."""
    # the run's flags through a view indexed from 0 (flags[t0 + j] pays numba's
    # negative-index wraparound in every vectorised loop that reads it: 10% of the setup)
    run_flags = flags[t0:t0 + count]
    for j in range(count):
        for k in range(3):
            for q in range(3):
                soa[3 * k + q, j] = corners[t0 + j, k, q]
    m00, m01, m02, m03 = m[0, 0], m[0, 1], m[0, 2], m[0, 3]
    m10, m11, m12, m13 = m[1, 0], m[1, 1], m[1, 2], m[1, 3]
    m20, m21, m22, m23 = m[2, 0], m[2, 1], m[2, 2], m[2, 3]
    m30, m31, m32, m33 = m[3, 0], m[3, 1], m[3, 2], m[3, 3]
    for k in range(3):
        for j in range(count):
            x = np.float64(soa[3 * k, j])
            y = np.float64(soa[3 * k + 1, j])
            z = np.float64(soa[3 * k + 2, j])
            clip[4 * k, j] = m00 * x + m01 * y + m02 * z + m03
            clip[4 * k + 1, j] = m10 * x + m11 * y + m12 * z + m13
            clip[4 * k + 2, j] = m20 * x + m21 * y + m22 * z + m23
            clip[4 * k + 3, j] = m30 * x + m31 * y + m32 * z + m33
    # status so far: 0 culled, 1 simple, 2 cut (by the guard band: screen coordinates
    # beyond it could overflow the fixed-point range)
    gx = planes[n_cut, 3]
    gy = planes[n_cut + 2, 3]
    for j in range(count):
        x0, y0, w0 = clip[0, j], clip[1, j], clip[3, j]
        x1, y1, w1 = clip[4, j], clip[5, j], clip[7, j]
        x2, y2, w2 = clip[8, j], clip[9, j], clip[11, j]
        out = (((x0 < -w0) & (x1 < -w1) & (x2 < -w2)) | ((x0 > w0) & (x1 > w1) & (x2 > w2))
               | ((y0 < -w0) & (y1 < -w1) & (y2 < -w2)) | ((y0 > w0) & (y1 > w1) & (y2 > w2))
               | ((run_flags[j] & FLAG_SKIP) != 0))
        cut = ((abs(x0) > gx * w0) | (abs(x1) > gx * w1) | (abs(x2) > gx * w2)
               | (abs(y0) > gy * w0) | (abs(y1) > gy * w1) | (abs(y2) > gy * w2))
        status[j] = _CULLED if out else (_CLIPPED if cut else _SIMPLE)
    for p in range(n_cut):
        a, b, c, d = planes[p, 0], planes[p, 1], planes[p, 2], planes[p, 3]
        for j in range(count):
            o0 = a * clip[0, j] + b * clip[1, j] + c * clip[2, j] + d * clip[3, j] < 0.0
            o1 = a * clip[4, j] + b * clip[5, j] + c * clip[6, j] + d * clip[7, j] < 0.0
            o2 = a * clip[8, j] + b * clip[9, j] + c * clip[10, j] + d * clip[11, j] < 0.0
            s = status[j]
            status[j] = _CULLED if (o0 & o1 & o2) | (s == _CULLED) else (
                _CLIPPED if o0 | o1 | o2 else s)
    for k in range(3):
        for j in range(count):
            simple = status[j] == _SIMPLE
            # only a simple triangle's corners are used (and safe to snap)
            w = clip[4 * k + 3, j] if simple else 1.0
            iw = 1.0 / w
            sx, sy = screen_from_ndc(clip[4 * k, j] * iw, clip[4 * k + 1, j] * iw, width,
                                     height)
            sx = sx if simple else 0.0
            sy = sy if simple else 0.0
            ints[2 * k * _CHUNK + j] = _snap(sx, scale)
            ints[(2 * k + 1) * _CHUNK + j] = _snap(sy, scale)
            floats[k * _CHUNK + j] = iw
    # the setups of the simple triangles (the others' are meaningless), their keep flag
    # in row 20: drawn, see _setup (one array for the ints, one for the floats, rows a
    # constant _CHUNK apart: the compiler sees they never overlap)
    c = _CHUNK
    for j in range(count):
        q = _setup(ints[j], ints[c + j], floats[j], ints[2 * c + j], ints[3 * c + j],
                   floats[c + j], ints[4 * c + j], ints[5 * c + j], floats[2 * c + j],
                   1.0 / MIRROR_TIE if run_flags[j] & FLAG_MIRROR else 1.0, cull, bits, top,
                   bottom, col0, col1)
        ints[20 * c + j] = q[0] & (status[j] == _SIMPLE)
        ints[6 * c + j] = q[1]
        ints[7 * c + j] = q[2]
        ints[8 * c + j] = q[3]
        ints[9 * c + j] = q[4]
        ints[10 * c + j] = q[5]
        ints[11 * c + j] = q[6]
        ints[12 * c + j] = q[7]
        ints[13 * c + j] = q[8]
        ints[14 * c + j] = q[9]
        ints[15 * c + j] = q[10]
        ints[16 * c + j] = q[11]
        ints[17 * c + j] = q[12]
        ints[18 * c + j] = q[13]
        ints[19 * c + j] = q[14]
        floats[3 * c + j] = q[15]
        floats[4 * c + j] = q[16]
        floats[5 * c + j] = q[17]
        floats[6 * c + j] = q[18]


@njit(cache=True, error_model="numpy")
def _draw_clipped(corners, t, key_scale, m, planes, width, height, bits, cull, scale, xyw,
                  row0, row1, col0, col1, stencil, use_stencil, floor, use_floor, tri, zbuf):
    """A triangle some plane cuts: its clipped polygon, culled by its winding, drawn as a
    fan of snapped triangles (sharing snapped corners: no cracks between them)."""
    n = _clip_polygon(corners, t, m, planes, width, height, xyw)
    if n < 3:
        return
    if cull != CULL_NONE:
        a = 0.0
        for i in range(1, n - 1):
            a += ((xyw[i, 0] - xyw[0, 0]) * (xyw[i + 1, 1] - xyw[0, 1])
                  - (xyw[i + 1, 0] - xyw[0, 0]) * (xyw[i, 1] - xyw[0, 1]))
        if (cull == CULL_BACK and a > 0.0) or (cull == CULL_FRONT and a < 0.0):
            return
    for i in range(1, n - 1):
        _fill(t, key_scale, CULL_NONE, _snap(xyw[0, 0], scale), _snap(xyw[0, 1], scale),
              xyw[0, 2], _snap(xyw[i, 0], scale), _snap(xyw[i, 1], scale), xyw[i, 2],
              _snap(xyw[i + 1, 0], scale), _snap(xyw[i + 1, 1], scale), xyw[i + 1, 2],
              bits, row0, row1, col0, col1, stencil, use_stencil, floor, use_floor,
              tri, zbuf)


@njit(cache=True, parallel=True, error_model="numpy")
def _resolve(flags, col0, col1, top, bottom, own_tri, own_key, drew, tri, depth):
    """Merge the threads' buffers (greatest key, then lowest triangle index) into `tri`, and
    eye depth w = 1 / (1/w) from the key (a mirror's divided by MIRROR_TIE); buffers of
    threads that drew nothing (`drew`) are left out. Pixels outside the box [top, bottom)
    x [col0, col1) get no triangle. Each row goes in passes without branches (they
    vectorise): the first drawing thread's buffers, the others' merged in, then the keys
    (kept in `depth` meanwhile) turned to depths."""
    h, w = tri.shape
    owners = np.flatnonzero(drew)
    for py in prange(h):
        inside = top <= py < bottom and owners.size > 0
        first, last = (col0, col1) if inside else (w, w)
        for px in range(min(first, w)):
            tri[py, px] = -1
            depth[py, px] = np.inf
        for px in range(last, w):
            tri[py, px] = -1
            depth[py, px] = np.inf
        if not inside:
            continue
        r = py - top
        n = col1 - col0
        row_tri = tri[py, col0:col1]
        row_key = depth[py, col0:col1]
        o = owners[0]
        for c in range(n):
            row_tri[c] = own_tri[o, r, c]
            row_key[c] = own_key[o, r, c]
        for j in range(1, owners.size):
            o = owners[j]
            for c in range(n):
                t, best = row_tri[c], row_key[c]
                tk, zk = own_tri[o, r, c], own_key[o, r, c]
                take = (zk > best) | ((zk == best) & (tk >= 0) & ((t < 0) | (tk < t)))
                row_tri[c] = tk if take else t
                row_key[c] = zk if take else best
        for c in range(n):
            t = row_tri[c]
            mirror = (flags[max(t, 0)] & FLAG_MIRROR) != 0
            iw = np.float64(row_key[c]) * (MIRROR_TIE if mirror else 1.0)
            row_key[c] = 1.0 / iw if t >= 0 else np.inf


@njit(cache=True, inline="always")
def clip_corners(corners, t, m):
    """Clip-space x, y and w of triangle t's corners (world `corners`, clip from world `m`):
    (x0, x1, x2, y0, y1, y2, w0, w1, w2), what barycentrics_at needs."""
    x0, y0, z0 = corners[t, 0, 0], corners[t, 0, 1], corners[t, 0, 2]  # float32 -> float64
    x1, y1, z1 = corners[t, 1, 0], corners[t, 1, 1], corners[t, 1, 2]
    x2, y2, z2 = corners[t, 2, 0], corners[t, 2, 1], corners[t, 2, 2]
    out = (m[0, 0] * x0 + m[0, 1] * y0 + m[0, 2] * z0 + m[0, 3],
           m[0, 0] * x1 + m[0, 1] * y1 + m[0, 2] * z1 + m[0, 3],
           m[0, 0] * x2 + m[0, 1] * y2 + m[0, 2] * z2 + m[0, 3],
           m[1, 0] * x0 + m[1, 1] * y0 + m[1, 2] * z0 + m[1, 3],
           m[1, 0] * x1 + m[1, 1] * y1 + m[1, 2] * z1 + m[1, 3],
           m[1, 0] * x2 + m[1, 1] * y2 + m[1, 2] * z2 + m[1, 3],
           m[3, 0] * x0 + m[3, 1] * y0 + m[3, 2] * z0 + m[3, 3],
           m[3, 0] * x1 + m[3, 1] * y1 + m[3, 2] * z1 + m[3, 3],
           m[3, 0] * x2 + m[3, 1] * y2 + m[3, 2] * z2 + m[3, 3])
    return out


@njit(cache=True, inline="always")
def barycentrics_at(c, nx, ny):
    """(b1, b2): weights of corners 1 and 2 at the point of the triangle's plane seen through
    NDC (nx, ny), from its clip_corners `c`: the weights are proportional to the 2D cross
    products of the other two corners' (x - nx w, y - ny w). Perspective-correct, and right
    for triangles the rasterizer clipped."""
    u0, u1, u2 = c[0] - nx * c[6], c[1] - nx * c[7], c[2] - nx * c[8]
    v0, v1, v2 = c[3] - ny * c[6], c[4] - ny * c[7], c[5] - ny * c[8]
    d0 = u1 * v2 - u2 * v1
    d1 = u2 * v0 - u0 * v2
    d2 = u0 * v1 - u1 * v0
    inv = 1.0 / (d0 + d1 + d2)
    return d1 * inv, d2 * inv


@njit(cache=True, inline="always")
def recover_barycentrics(corners, t, m, nx, ny):
    """(b1, b2) of triangle t at NDC (nx, ny): barycentrics_at of its clip_corners."""
    return barycentrics_at(clip_corners(corners, t, m), nx, ny)


@njit(cache=True, parallel=True, error_model="numpy")
def _barycentrics(tri, corners, m, b1, b2):
    """b1, b2 of every pixel's triangle (0 where none), by recover_barycentrics."""
    h, w = tri.shape
    for py in prange(h):
        ny = 1.0 - (py + 0.5) * (2.0 / h)
        for px in range(w):
            t = tri[py, px]
            if t < 0:
                b1[py, px] = 0.0
                b2[py, px] = 0.0
                continue
            c1, c2 = recover_barycentrics(corners, t, m, (px + 0.5) * (2.0 / w) - 1.0, ny)
            b1[py, px] = c1
            b2[py, px] = c2
