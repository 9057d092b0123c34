"""Drawing a set-up triangle's pixels: the row walk (`_rows`) with the depth test, the same
for a box of at most 2 x 2 pixels without the walk (`_quad`), and `_fill_at` (setup then
either) for one triangle (clipped triangles' fans); `_fill` is the same into buffers of the
triangle's own box, the entry its exact pixel-by-pixel twin drives."""

import numpy as np
from numba import njit

from .constants import _BLOCK
from .setup import _setup


@njit(cache=True, inline="always")
def _rows(t32, xs, n, ys, ye, first_y, e0, e1, e2, sa0, sa1, sa2, sb0, sb1, sb2, z_ref,
          dzdx, dzdy, zx0, tie, top, col0, stencil, use_stencil, floor, use_floor, tri, key,
          blocks, want):
    """Draw the pixels of rows ys..ye, columns xs..xs+n-1 whose centers are inside (every
    edge function >= 0) into the box buffers (pixel (py, px) at [py - top, px - col0]).

    `blocks`: the buffers have _BLOCK - 1 columns to spare past the box, so a plain row is
    walked in whole blocks of _BLOCK. A row's pixels are read through views starting at
    column xs, indexed from 0: indexed [r, xs - col0 + k], numba's negative-index
    wraparound kept the plain loop scalar (with spills); this way it vectorises.

    `want` < 0: a pixel is on the stencil where it is not 0; else where it equals `want`
    (a stencil of labels, several passes drawn at once: `rasterize_passes`)."""
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
                        plain or ((not use_stencil or (stencil[py, xs + k] != 0 if want < 0
                                                       else stencil[py, xs + k] == want))
                                  and (not use_floor or zf * tie * floor[py, xs + k] < 1.0))):
                    key[r, c + k] = z
                    tri[r, c + k] = t32
            f0 += sa0
            f1 += sa1
            f2 += sa2
        e0 += sb0
        e1 += sb1
        e2 += sb2


@njit(cache=True, inline="always")
def _narrow(t32, xs, n, ys, ye, first_y, e0, e1, e2, sa0, sa1, sa2, sb0, sb1, sb2, z_ref,
            dzdx, dzdy, zx0, top, col0, tri, key, width):
    """`_rows`'s plain walk (no stencil, no floor) for a box at most `width` pixels wide
    (n <= width, a constant: _BLOCK or _NARROW; the buffers have width - 1 columns to spare
    past the box): each row walked over `width` pixels, a loop of constant length the
    compiler unrolls (`_rows` walks its blocks with a loop of unknown length), with
    `_rows`'s arithmetic and test; the pixels past the box (k >= n) written back
    unchanged."""
    c = np.uint64(xs - col0)  # unsigned indices (all are >= 0): no negative-index wraparound
    for py in range(ys, ye + 1):
        z_row = z_ref + dzdy * (py - first_y) + zx0
        r = np.uint64(py - top)
        f0, f1, f2 = e0, e1, e2
        for k in range(width):
            z = np.float32(z_row + dzdx * k)
            old = key[r, c + np.uint64(k)]
            was = tri[r, c + np.uint64(k)]
            win = (((f0 | f1 | f2) >= 0) & (k < n)
                   & ((z > old) | ((z == old) & (t32 < was))))
            key[r, c + np.uint64(k)] = z if win else old
            tri[r, c + np.uint64(k)] = t32 if win else was
            f0 += sa0
            f1 += sa1
            f2 += sa2
        e0 += sb0
        e1 += sb1
        e2 += sb2


@njit(cache=True, inline="always")
def _pixel(t32, py, px, r, c, f0, f1, f2, z, zf, tie, ok, stencil, use_stencil, floor,
           use_floor, tri, key, want):
    """One pixel of `_quad`: `_rows`'s test (center inside, key greater or equal with a lower
    index, stencil, floor) and write, without a branch but on `use_stencil` and `use_floor`
    (the same for every pixel of a draw); `ok` False writes the pixel back unchanged."""
    old = key[r, c]
    was = tri[r, c]
    win = (((f0 | f1 | f2) >= 0) & ok & ((z > old) | ((z == old) & (t32 < was))))
    if use_stencil:
        s = stencil[py, px]
        win &= (s != 0) if want < 0 else (s == want)
    if use_floor:
        win &= zf * tie * floor[py, px] < 1.0
    key[r, c] = z if win else old
    tri[r, c] = t32 if win else was


@njit(cache=True, inline="always")
def _quad(t32, xs, n, ys, ye, first_y, e0, e1, e2, sa0, sa1, sa2, sb0, sb1, sb2, z_ref,
          dzdx, dzdy, zx0, tie, top, col0, stencil, use_stencil, floor, use_floor, tri, key,
          want):
    """`_rows` for a box of at most 2 x 2 pixels (n <= 2, ye <= ys + 1; 82% of the drawn
    triangles at 1M): its 4 pixels tested and written without the row and block loops,
    each with `_rows`'s arithmetic (the same keys, the same tests). The buffers have a row
    and a column to spare past the box: a pixel past the box is read and written back
    unchanged (its stencil and floor read at the box's last pixel instead), so the 4 never
    share a place in the buffers."""
    wide = n > 1
    tall = ye > ys
    # stencil and floor (whole images): a pixel past the box reads the box's last one
    x1 = xs + wide
    y1 = ys + tall
    # unsigned indices (all are >= 0): numba then adds no negative-index wraparound
    c0 = np.uint64(xs - col0)
    r0 = np.uint64(ys - top)
    c1 = c0 + np.uint64(1)
    r1 = r0 + np.uint64(1)
    z_row0 = z_ref + dzdy * (ys - first_y) + zx0
    z_row1 = z_ref + dzdy * (ys + 1 - first_y) + zx0
    one, zero = np.int64(1), np.int64(0)
    zf = z_row0 + dzdx * zero
    _pixel(t32, ys, xs, r0, c0, e0, e1, e2, np.float32(zf), zf, tie, True, stencil,
           use_stencil, floor, use_floor, tri, key, want)
    zf = z_row0 + dzdx * one
    _pixel(t32, ys, x1, r0, c1, e0 + sa0, e1 + sa1, e2 + sa2, np.float32(zf), zf, tie,
           wide, stencil, use_stencil, floor, use_floor, tri, key, want)
    zf = z_row1 + dzdx * zero
    _pixel(t32, y1, xs, r1, c0, e0 + sb0, e1 + sb1, e2 + sb2, np.float32(zf), zf, tie,
           tall, stencil, use_stencil, floor, use_floor, tri, key, want)
    zf = z_row1 + dzdx * one
    _pixel(t32, y1, x1, r1, c1, e0 + sa0 + sb0, e1 + sa1 + sb1, e2 + sa2 + sb2,
           np.float32(zf), zf, tie, wide & tall, stencil, use_stencil, floor, use_floor,
           tri, key, want)


@njit(cache=True, error_model="numpy")
def _fill(t, key_scale, cull, x0, y0, w0, x1, y1, w1, x2, y2, w2, bits, top, bottom, col0,
          col1, stencil, use_stencil, floor, use_floor, tri, key):
    """Draw one snapped screen triangle into the box [top, bottom) x [col0, col1) (`tri`
    and `key` hold the box: pixel (py, px) at [py - top, px - col0]): `_setup` then `_rows`.

    (x, y): corners in units of 2^-bits pixel (int64); w0..w2 their 1/w. A pixel is drawn
    where its center is inside (top-left rule), its stencil is set (`use_stencil`), its
    depth w is beyond floor's (`use_floor`), and its key 1/w * key_scale is greater than
    the stored one, or equal to it with a lower triangle index. `cull` as in rasterize."""
    _fill_at(t, key_scale, cull, x0, y0, w0, x1, y1, w1, x2, y2, w2, bits, top, bottom, col0,
             col1, stencil, use_stencil, floor, use_floor, tri, key, top, col0, -1)


@njit(cache=True, inline="always", error_model="numpy")
def _fill_at(t, key_scale, cull, x0, y0, w0, x1, y1, w1, x2, y2, w2, bits, top, bottom, col0,
             col1, stencil, use_stencil, floor, use_floor, tri, key, origin_y, origin_x, want):
    """`_fill` into buffers holding a box with corner (origin_y, origin_x) that holds the
    box [top, bottom) x [col0, col1) the triangle is clipped to (pixel (py, px) at
    [py - origin_y, px - origin_x]); `want` as in `_rows`."""
    s = _setup(np.int64(x0), np.int64(y0), np.float64(w0), np.int64(x1), np.int64(y1),
               np.float64(w1), np.int64(x2), np.int64(y2), np.float64(w2),
               np.float64(key_scale), cull, bits, top, bottom, col0, col1)
    if not s[0]:
        return
    # `_quad` for a box of at most 2 x 2 pixels in buffers with a row and a column to spare
    if (s[2] <= 2 and s[4] <= s[3] + 1 and key.shape[0] > bottom - origin_y
            and key.shape[1] > col1 - origin_x):
        _quad(np.int32(t), s[1], s[2], s[3], s[4], s[5], s[6], s[7], s[8], s[9], s[10],
              s[11], s[12], s[13], s[14], s[15], s[16], s[17], s[18], 1.0 / key_scale,
              origin_y, origin_x, stencil, use_stencil, floor, use_floor, tri, key, want)
        return
    _rows(np.int32(t), s[1], s[2], s[3], s[4], s[5], s[6], s[7], s[8], s[9], s[10], s[11],
          s[12], s[13], s[14], s[15], s[16], s[17], s[18], 1.0 / key_scale, origin_y,
          origin_x, stencil, use_stencil, floor, use_floor, tri, key,
          key.shape[1] >= col1 - origin_x + _BLOCK - 1, want)
