"""The parallel draw: runs of triangles claimed by whichever thread is free, each drawn
into that thread's own buffers (`_draw`); triangles a plane cuts go as fans of their clipped
polygon (`_draw_clipped`)."""

import numpy as np
from numba import njit, prange

from ...parallel import claim, counter
from ...scene.types import MIRROR_TIE
from .clip import _box_misses, _clip_polygon
from .constants import (
    _BLOCK,
    _CHUNK,
    _CLIPPED,
    _MAX_POLY,
    _NARROW,
    CULL_BACK,
    CULL_FRONT,
    CULL_NONE,
    FLAG_MIRROR,
)
from .fixed import _snap
from .rows import _fill_at, _narrow, _quad, _rows
from .setup import _run_setup, triangle_cull


@njit(cache=True, parallel=True, error_model="numpy")
def _draw(corners, flags, m, planes, n_cut, width, height, bits, cull, chunks, bounds, stencil,
          use_stencil, floor, use_floor, col0, col1, top, bottom, own_tri, own_key, drew):
    """Every triangle, in chunks of _CHUNK, into the buffers of the thread drawing it;
    chunks whose world box (`bounds`, if given) misses the view or the box are skipped. A
    thread clears its buffers before its first chunk and marks them in `drew` (one parallel
    region less: on a busy machine each costs a wake-up of the other threads).

    A chunk goes in two phases: `_run_setup` (clip space, classification, projection,
    snapping and a cheap test of facing and covered centres, then edge functions and key
    planes of the triangles that test lists: loops without branches over the run, which
    the compiler vectorises, into small per-thread arrays), then `_fill_listed` (each
    listed triangle's pixels) and `_draw_clipped` for the triangles a plane cuts."""
    n = corners.shape[0]
    scale = float(1 << bits)
    threads = own_tri.shape[0]
    work_i = np.empty((threads, 22 * _CHUNK), np.int64)
    work_f = np.empty((threads, 8 * _CHUNK))
    status = np.empty((threads, _CHUNK), np.uint8)
    chosen = np.empty((threads, 4 * _CHUNK), np.int64)
    xyw = np.empty((threads, _MAX_POLY, 3))
    # one item per thread, each claiming the next chunk until none is left (parallel.py);
    # a worker draws into its own buffers, merged by key: who drew what never matters
    claimed = counter()
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
            kept = _run_setup(corners, flags, m, planes, n_cut, width, height, bits, scale,
                              cull, top, bottom, col0, col1, t0, count,
                              work_i[me], work_f[me], status[me])
            ints = work_i[me]
            floats = work_f[me]
            st = status[me]
            sel = chosen[me]
            _fill_listed(ints, floats, sel, kept, t0, flags, top, col0, stencil, use_stencil,
                         floor, use_floor, tri, key, -1)
            clipped = 0
            for j in range(count):
                clipped += st[j] == _CLIPPED
            if clipped:
                for j in range(count):
                    if st[j] == _CLIPPED:
                        t = t0 + j
                        # (want -1 as an int64, not a constant: the passes' signature)
                        _draw_clipped(corners, t, 1.0 / MIRROR_TIE if flags[t] & FLAG_MIRROR
                                      else 1.0, m, planes, width, height, bits,
                                      triangle_cull(flags[t], cull), scale, xyw[me], top,
                                      bottom, col0, col1, stencil, use_stencil, floor,
                                      use_floor, tri, key, top, col0, np.int64(-1))


@njit(cache=True, inline="always", error_model="numpy")
def _fill_listed(ints, floats, sel, kept, t0, flags, top, col0, stencil, use_stencil, floor,
                 use_floor, tri, key, want):
    """Fill the `kept` triangles a run's `_run_setup` listed (setup columns 0..kept-1 of
    ints / floats, row 21 their index in the run from t0), those it found drawn: listed
    without a branch per triangle into four parts of `sel`: a plain draw (no stencil, no
    floor) walks boxes at most 2, 4 or 8 pixels wide with `_narrow` (rows of that constant
    width); else boxes of at most 2 x 2 pixels go to `_quad`; the others to `_rows`. Which
    of these draws a triangle never changes its pixels. `draw` and `rasterize_passes`
    share it. `sel`: 4 * _CHUNK."""
    c = _CHUNK
    k = 0
    w4 = 0
    w8 = 0
    b = 0
    plain = not use_stencil and not use_floor
    for i in range(kept):
        drawn = ints[20 * c + i]
        n = ints[7 * c + i]
        # plain: a box at most 2, 4 or 8 pixels wide (`_narrow`); else at most 2 x 2
        # (`_quad`); the others `_rows`
        small = (n <= 2) & (plain | (ints[9 * c + i] <= ints[8 * c + i] + 1))
        mid4 = plain & (n > 2) & (n <= _BLOCK)
        mid8 = plain & (n > _BLOCK) & (n <= _NARROW)
        sel[k] = i
        sel[c + w4] = i
        sel[2 * c + w8] = i
        sel[4 * c - 1 - b] = i
        quad = drawn & small
        four = drawn & mid4
        eight = drawn & mid8
        k += quad
        w4 += four
        w8 += eight
        b += drawn - quad - four - eight
    for q in range(w4):
        _narrow_at(ints, floats, c, sel[c + q], t0, top, col0, tri, key, _BLOCK)
    for q in range(w8):
        _narrow_at(ints, floats, c, sel[2 * c + q], t0, top, col0, tri, key, _NARROW)
    for q in range(k):
        j = sel[q]
        if plain:
            _narrow_at(ints, floats, c, j, t0, top, col0, tri, key, 2)
            continue
        t = t0 + ints[21 * c + j]
        _quad(np.int32(t), ints[6 * c + j], ints[7 * c + j], ints[8 * c + j],
              ints[9 * c + j], ints[10 * c + j], ints[11 * c + j], ints[12 * c + j],
              ints[13 * c + j], ints[14 * c + j], ints[15 * c + j], ints[16 * c + j],
              ints[17 * c + j], ints[18 * c + j], ints[19 * c + j], floats[3 * c + j],
              floats[4 * c + j], floats[5 * c + j], floats[6 * c + j],
              MIRROR_TIE if flags[t] & FLAG_MIRROR else 1.0, top, col0, stencil,
              use_stencil, floor, use_floor, tri, key, want)
    for q in range(b):
        j = sel[4 * c - 1 - q]
        t = t0 + ints[21 * c + j]
        _rows(np.int32(t), ints[6 * c + j], ints[7 * c + j], ints[8 * c + j],
              ints[9 * c + j], ints[10 * c + j], ints[11 * c + j], ints[12 * c + j],
              ints[13 * c + j], ints[14 * c + j], ints[15 * c + j], ints[16 * c + j],
              ints[17 * c + j], ints[18 * c + j], ints[19 * c + j], floats[3 * c + j],
              floats[4 * c + j], floats[5 * c + j], floats[6 * c + j],
              MIRROR_TIE if flags[t] & FLAG_MIRROR else 1.0, top, col0, stencil,
              use_stencil, floor, use_floor, tri, key, True, want)


@njit(cache=True, inline="always")
def _narrow_at(ints, floats, c, j, t0, top, col0, tri, key, width):
    """`_narrow` (rows `width` pixels wide, a constant) of the set-up triangle in column j."""
    _narrow(np.int32(t0 + ints[21 * c + j]), ints[6 * c + j], ints[7 * c + j], ints[8 * c + j],
            ints[9 * c + j], ints[10 * c + j], ints[11 * c + j], ints[12 * c + j],
            ints[13 * c + j], ints[14 * c + j], ints[15 * c + j], ints[16 * c + j],
            ints[17 * c + j], ints[18 * c + j], ints[19 * c + j], floats[3 * c + j],
            floats[4 * c + j], floats[5 * c + j], floats[6 * c + j], top, col0, tri, key,
            width)


@njit(cache=True, error_model="numpy")
def _draw_clipped(corners, t, key_scale, m, planes, width, height, bits, cull, scale, xyw,
                  row0, row1, col0, col1, stencil, use_stencil, floor, use_floor, tri, zbuf,
                  origin_y, origin_x, want):
    """A triangle some plane cuts: its clipped polygon, culled by its winding, drawn as a
    fan of snapped triangles (sharing snapped corners: no cracks between them) into the box
    [row0, row1) x [col0, col1) of buffers whose corner is (origin_y, origin_x); `want` as
    in `_rows`."""
    n = _clip_polygon(corners, t, m, planes, width, height, xyw)
    if n < 3:
        return
    if cull != CULL_NONE:
        a = 0.0
        for i in range(1, n - 1):
            a += ((xyw[i, 0] - xyw[0, 0]) * (xyw[i + 1, 1] - xyw[0, 1])
                  - (xyw[i + 1, 0] - xyw[0, 0]) * (xyw[i, 1] - xyw[0, 1]))
        if ((cull & CULL_BACK) != 0 and a > 0.0) or ((cull & CULL_FRONT) != 0 and a < 0.0):
            return
    for i in range(1, n - 1):
        _fill_at(t, key_scale, CULL_NONE, _snap(xyw[0, 0], scale), _snap(xyw[0, 1], scale),
                 xyw[0, 2], _snap(xyw[i, 0], scale), _snap(xyw[i, 1], scale), xyw[i, 2],
                 _snap(xyw[i + 1, 0], scale), _snap(xyw[i + 1, 1], scale), xyw[i + 1, 2],
                 bits, row0, row1, col0, col1, stencil, use_stencil, floor, use_floor,
                 tri, zbuf, origin_y, origin_x, want)
