"""Zexels' payload rows (colour, triangle...) carried to the pixels they reach: the
helpers the splats copy rows with, and the gather pass for the splats that do not."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

# maps whose rows a spread copies itself (`_copy_zexel_rows`), handed as a tuple of this
# many arrays whatever their count: one signature of the kernel for 1 to 4 maps
MAPS_AT_ONCE = 4


@njit(cache=True, inline="always")
def _copy_zexel_rows(ids, rows, n_maps, shift, dst, base):
    """dst[base + i] = the row of zexel ids[i] from its map (ids slot << shift | index), for
    the pixels of a row a zexel reached; `rows`: a tuple whose first n_maps arrays are the
    maps' rows. One pass a map, each taking its map's array once: a tuple indexed per pixel
    copies the array's handle (with its reference count) each time, which cost more than
    the copy. With one map, every pixel gets a row, without a branch (a pixel no zexel
    reached gets the first row, whose value does not matter)."""
    n = ids.shape[0]
    if n_maps == 1:
        src = rows[0]
        if src.shape[1] == 3:  # colour: flat, constant offsets
            s = src.reshape(-1)
            d = dst.reshape(-1)
            for i in range(n):
                k = 3 * max(ids[i], 0)
                q = 3 * (base + i)
                d[q] = s[k]
                d[q + 1] = s[k + 1]
                d[q + 2] = s[k + 2]
            return
        for i in range(n):
            _copy_row(src, max(ids[i], 0), dst, base + i)
        return
    for slot in range(n_maps):
        src = rows[slot]
        for i in range(n):
            q = ids[i]
            if q >= 0 and q >> shift == slot:
                _copy_row(src, q - (slot << shift), dst, base + i)


@njit(cache=True, inline="always")
def _copy_row(src, k, dst, p):
    """dst[p] = src[k], with the common widths (3: colour, 4: colour and triangle) as
    constant loops."""
    c = src.shape[1]
    if c == 3:
        for j in range(3):
            dst[p, j] = src[k, j]
    elif c == 4:
        for j in range(4):
            dst[p, j] = src[k, j]
    else:
        for j in range(c):
            dst[p, j] = src[k, j]


def _payload_args(payload, payload_out):
    """(payload (n, c), payload_out flattened to (H * W, c)), or empty stand-ins."""
    if payload is None:
        return np.empty((0, 1), np.float32), np.empty((0, 1), np.float32)
    if not payload_out.flags.c_contiguous:
        raise ValueError("payload_out must be C-contiguous (its rows are written in place)")
    c = payload.shape[1]
    return np.ascontiguousarray(payload), payload_out.reshape(-1, c)


def _payload_flat(payload, payload_out):
    """(payload (n, c) flat, payload_out (H, W, c) flat, c), or empty stand-ins and width 0
    without a payload."""
    if payload is None:
        empty = np.empty(0, np.float32)
        return empty, empty, 0
    pay, pay_out = _payload_args(payload, payload_out)
    return pay.reshape(-1), pay_out.reshape(-1), pay.shape[1]


def gather_colors(best_id: np.ndarray, stride: int, per_map: list[np.ndarray],
                  box: tuple[int, int, int, int], out: np.ndarray) -> None:
    """out[y, x] = the row of per_map[slot] (each (n, c)) for the warp id at each pixel of
    `box` = (x0, x1, y0, y1) that a zexel reached (id = slot * stride + index); other pixels
    of the box are left alone. Up to four maps a pass (one signature for any count)."""
    x0, x1, y0, y1 = box
    shift = stride.bit_length() - 1 if stride & (stride - 1) == 0 else -1
    for first in range(0, len(per_map), 4):
        group = per_map[first:first + 4]
        group = group + [group[0]] * (4 - len(group))
        _gather4(best_id, stride, shift, first, len(per_map[first:first + 4]), group[0],
                 group[1], group[2], group[3], x0, x1, y0, y1, out)


@njit(cache=True, parallel=True)
def _gather4(best_id, stride, shift, first, n, c0, c1, c2, c3, x0, x1, y0, y1, out):
    # shift >= 0: stride = 2^shift, the slot without a division
    channels = out.shape[2]
    for y in prange(y0, y1):
        for x in range(x0, x1):
            ident = best_id[y, x]
            if ident < 0:
                continue
            if shift >= 0:
                s = ident >> shift
                k = ident & (stride - 1)
            else:
                s = ident // stride
                k = ident - s * stride
            slot = s - first
            if slot < 0 or slot >= n:
                continue
            src = c0 if slot == 0 else c1 if slot == 1 else c2 if slot == 2 else c3
            for c in range(channels):
                out[y, x, c] = src[k, c]
