"""Fixed splats wider than a pixel in z-buffer mode, as a `spread` of the one-pixel result:
over its (2r + 1)^2 square a pixel keeps its own zexel if that is on the square's front
surface, else the nearest kept zexel (least (depth, id): a separable minimum over packed
integer keys, as a z-buffered splat of the one-pixel result would) of the smallest square
around it (radius 1, 2, ..., r) whose nearest is on that front surface."""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

from .payload import MAPS_AT_ONCE, _copy_zexel_rows, _payload_args, gather_colors
from .visibility import SAME_SURFACE

# key of no zexel in `spread`: above every (depth bits, id) key, inf depths included
_NO_KEY = np.int64(0x7FFFFFFFFFFFFFFF)


def spread(best_zd, best_id, radius: int, stencil, box, out_z, out_id, payloads=None,
           stride: int = 1, payload_out=None, bands: int | None = None) -> None:
    """A splat of (2 radius + 1)^2 pixels from the one-pixel splat's result (`best_zd` (H,
    W, 2): depth, distance; best_id). Each kept zexel has the key (float32 depth bits, id)
    (bits of a non-negative float order as the float does): of the kept zexels in the
    square around a stencil pixel of `box` = (x0, x1, y0, y1), the one with the least key
    is the nearest (ties to the lower id), and the front surface is those within
    SAME_SURFACE of its depth (or equal to it: at infinity). The pixel keeps its own zexel
    if that is on the front surface (where zexels are dense, the wide splat is the one-pixel
    one); else, of the squares of radius 1, 2, ..., radius around it, it takes the least
    key's zexel of the first whose least key is on the front surface (so a hole takes a
    near neighbour). The least key over a square is a separable minimum (over the square's
    rows, then its columns). Writes out_z / out_id over the box
    (inf / -1 off the stencil). `payloads`: per map (n, c) rows, ids slot * stride + index
    (stride a power of two); each pixel of the box gets its zexel's row in `payload_out`
    (H, W, c), so the one-pixel splat need not write rows (with one map every pixel gets
    one, without a branch: pixels no zexel reached, or off the stencil, receive some row).
    The kernel takes the maps' rows as MAPS_AT_ONCE arrays, whatever their count (a tuple
    of each length compiled it again, a minute each); more maps than that get their rows
    from `gather_colors` after the spread (the reached pixels' rows: the same bytes)."""
    x0, x1, y0, y1 = box
    with_payload = payloads is not None and len(payloads) <= MAPS_AT_ONCE
    if with_payload:
        rows = [np.ascontiguousarray(p) for p in payloads]
        _, pay_out = _payload_args(rows[0], payload_out)
        n_maps = len(rows)
    else:
        rows = [np.empty((0, 1), np.float32)]
        pay_out = rows[0]
        n_maps = 1
    rows = tuple(rows + rows[:1] * (MAPS_AT_ONCE - n_maps))  # the unused ones never read
    zd = np.ascontiguousarray(best_zd).reshape(-1)
    if bands is None:
        bands = max(1, numba.get_num_threads()) * 4
    _spread(zd, zd.view(np.int32), np.ascontiguousarray(best_id).reshape(-1), radius,
            stencil, x0, x1, y0, y1, best_id.shape[0], best_id.shape[1], out_z, out_id,
            with_payload, rows, n_maps, stride.bit_length() - 1, pay_out, bands)
    if payloads is not None and not with_payload:
        gather_colors(out_id, stride, list(payloads), box, payload_out)


@njit(cache=True, parallel=True, error_model="numpy")
def _spread(zd, bits, idf, r, stencil, x0, x1, y0, y1, h, w, out_z, out_id, with_payload, rows,
            n_maps, shift, pay_out, bands):
    # bands of rows, each run top to bottom with a ring of the 2r + 1 rows' keys around its
    # row (each pixel's key made once a band); a pixel's result depends on its square only
    for b in prange(bands):
        ya = y0 + (y1 - y0) * b // bands
        yb = y0 + (y1 - y0) * (b + 1) // bands
        if yb <= ya:
            continue
        # the common radii as constants: their loops unroll
        if r == 1:
            _spread_band(zd, bits, idf, 1, stencil, x0, x1, ya, yb, h, w, out_z, out_id,
                         with_payload, rows, n_maps, shift, pay_out)
        elif r == 2:
            _spread_band_rings(zd, bits, idf, 2, stencil, x0, x1, ya, yb, h, w, out_z, out_id,
                               with_payload, rows, n_maps, shift, pay_out)
        else:
            _spread_band_rings(zd, bits, idf, r, stencil, x0, x1, ya, yb, h, w, out_z, out_id,
                               with_payload, rows, n_maps, shift, pay_out)


@njit(cache=True, inline="always")
def _spread_band(zd, bits, idf, r, stencil, x0, x1, ya, yb, h, w, out_z, out_id, with_payload,
                 rows, n_maps, shift, pay_out):
    """Rows [ya, yb) of `spread`. Neighbours off the screen are replaced by the nearest pixel
    on it (clamped coordinates): a pixel counted twice changes no minimum."""
    xa = max(x0 - r, 0)
    n_col = min(x1 + r, w) - xa
    n = x1 - x0
    size = 2 * r + 1
    ring = np.empty((size, n_col), np.int64)  # ring[(yy + r) % size]: keys of row clamp(yy)
    for yy in range(ya - r, ya + r):
        _key_row(ring[(yy + r) % size], bits, idf, min(max(yy, 0), h - 1) * w + xa)
    padded = np.full(n_col + 2 * r, _NO_KEY, np.int64)
    least = np.empty(n, np.int64)
    front_bits = np.empty(n, np.int32)
    own_z = np.empty(n, np.float32)  # the pixels' own depths, contiguous
    front = front_bits.view(np.float32)
    for y in range(ya, yb):
        _key_row(ring[(y + 2 * r) % size], bits, idf, min(y + r, h - 1) * w + xa)
        # the square's least key: a column minimum over its rows (into a row padded with no
        # key: the clamped columns repeat an edge column already in the square), then a row
        # minimum
        column = padded[r:r + n_col]  # column[i]: screen column xa + i
        column[:] = ring[0]
        for j in range(1, size):
            _min_into(column, ring[j])
        least[:] = padded[x0 - xa:x0 - xa + n]
        for dx in range(1, 2 * r + 1):
            _min_into(least, padded[x0 - xa + dx:x0 - xa + dx + n])
        for i in range(n):  # the least key's depth, as float32 (its high bits)
            front_bits[i] = np.int32(least[i] >> 32)
        # a pixel whose own zexel is on the front surface keeps it (no branches); the others
        # (holes of the one-pixel splat, or behind a nearer neighbour) take the least key's
        base = y * w + x0
        _own_depths(zd[2 * base:2 * (base + n)], own_z)
        _spread_pick(own_z, idf[base:base + n], least, front,
                     stencil[y, x0:x1], out_z[y, x0:x1], out_id[y, x0:x1])
        if with_payload:  # each pixel's zexel's row from its map
            _copy_zexel_rows(out_id[y, x0:x1], rows, n_maps, shift, pay_out, base)


@njit(cache=True, inline="always")
def _spread_pick(own_z, own, least, front, on, oz, oi):
    """One row's choice: own zexel if on the front surface, else the least key's (`own_z`:
    the own zexels' depths, a contiguous row: read with the (depth, distance) stride, the
    loop did not vectorize and took three times as long)."""
    inf = np.float32(np.inf)
    for i in range(own.shape[0]):
        zo = own_z[i]
        fz = front[i]
        keep = (own[i] >= 0) & ((zo <= fz * (1.0 + SAME_SURFACE)) | (zo == fz))
        key = least[i]
        found = key != _NO_KEY
        z_other = fz if found else inf
        id_other = (key & 0xFFFFFFFF) if found else np.int64(-1)
        z_pick = zo if keep else z_other
        id_pick = own[i] if keep else id_other
        oz[i] = z_pick if on[i] else inf
        oi[i] = id_pick if on[i] else np.int64(-1)


@njit(cache=True, inline="always")
def _spread_band_rings(zd, bits, idf, r, stencil, x0, x1, ya, yb, h, w, out_z, out_id,
                       with_payload, rows, n_maps, shift, pay_out):
    """`_spread_band` for r > 1: a hole takes the least key of the smallest square around
    it whose least key is on the front surface (its own function: in `_spread_band` the
    squares' loop slows r = 1 by a fifth)."""
    xa = max(x0 - r, 0)
    n_col = min(x1 + r, w) - xa
    n = x1 - x0
    size = 2 * r + 1
    ring = np.empty((size, n_col), np.int64)  # ring[(yy + r) % size]: keys of row clamp(yy)
    for yy in range(ya - r, ya + r):
        _key_row(ring[(yy + r) % size], bits, idf, min(max(yy, 0), h - 1) * w + xa)
    padded = np.full(n_col + 2 * r, _NO_KEY, np.int64)
    least = np.empty(n, np.int64)
    pick = np.empty(n, np.int64)
    inner = np.empty((max(r - 1, 1), n), np.int64)  # inner[k - 1]: squares of radius k < r
    front_bits = np.empty(n, np.int32)
    own_z = np.empty(n, np.float32)  # the pixels' own depths, contiguous
    front = front_bits.view(np.float32)
    pick_bits = np.empty(n, np.int32)
    pick_z = pick_bits.view(np.float32)
    for y in range(ya, yb):
        _key_row(ring[(y + 2 * r) % size], bits, idf, min(y + r, h - 1) * w + xa)
        # the least key of the square of radius k = 1..r around each pixel: a column
        # minimum over its rows (into a row padded with no key: the clamped columns repeat an
        # edge column already in the square), then a row minimum. `least` ends with the
        # whole square's (the front surface's depth), `pick` with the smallest square's
        # whose least key is on that front surface
        column = padded[r:r + n_col]  # column[i]: screen column xa + i
        base = y * w + x0
        column[:] = ring[(y + r) % size]
        for k in range(1, r + 1):
            _min_into(column, ring[(y + r - k) % size])
            _min_into(column, ring[(y + r + k) % size])
            ring_least = least if k == r else inner[k - 1]
            ring_least[:] = padded[x0 - xa + r - k:x0 - xa + r - k + n]
            for dx in range(r - k + 1, r + k + 1):
                _min_into(ring_least, padded[x0 - xa + dx:x0 - xa + dx + n])
        for i in range(n):  # the least key's depth, as float32 (its high bits)
            front_bits[i] = np.int32(least[i] >> 32)
        pick[:] = least
        for k in range(r - 1, 0, -1):  # smaller squares win where on the front surface
            _nearer_ring(pick, inner[k - 1], front, pick_bits)
        for i in range(n):  # the picked key's depth
            pick_bits[i] = np.int32(pick[i] >> 32)
        # the same choice, with the picked key instead of the least
        _own_depths(zd[2 * base:2 * (base + n)], own_z)
        _spread_pick_ring(own_z, idf[base:base + n], pick, front, pick_z,
                          stencil[y, x0:x1], out_z[y, x0:x1], out_id[y, x0:x1])
        if with_payload:  # each pixel's zexel's row from its map
            _copy_zexel_rows(out_id[y, x0:x1], rows, n_maps, shift, pay_out, base)


@njit(cache=True, inline="always")
def _spread_pick_ring(own_z, own, pick, front, pick_z, on, oz, oi):
    """`_spread_pick` with the picked key's depth given (a smaller square's key)."""
    inf = np.float32(np.inf)
    for i in range(own.shape[0]):
        zo = own_z[i]
        fz = front[i]
        keep = (own[i] >= 0) & ((zo <= fz * (1.0 + SAME_SURFACE)) | (zo == fz))
        key = pick[i]
        found = key != _NO_KEY
        z_other = pick_z[i] if found else inf
        id_other = (key & 0xFFFFFFFF) if found else np.int64(-1)
        z_pick = zo if keep else z_other
        id_pick = own[i] if keep else id_other
        oz[i] = z_pick if on[i] else inf
        oi[i] = id_pick if on[i] else np.int64(-1)


@njit(cache=True, inline="always")
def _nearer_ring(pick, ring_least, front, scratch):
    """pick[i] = ring_least[i] where that key's depth is on the front surface (`scratch`: an
    int32 row for the depths' bits)."""
    for i in range(pick.shape[0]):
        scratch[i] = np.int32(ring_least[i] >> 32)
    z = scratch.view(np.float32)
    for i in range(pick.shape[0]):
        key = ring_least[i]
        f = front[i]
        on = (key != _NO_KEY) & ((z[i] <= f * (1.0 + SAME_SURFACE)) | (z[i] == f))
        pick[i] = key if on else pick[i]


@njit(cache=True, inline="always")
def _own_depths(zd, own_z):
    """own_z[i] = zd[2 i]: a row's depths out of its (depth, distance) records."""
    for i in range(own_z.shape[0]):
        own_z[i] = zd[2 * i]


@njit(cache=True, inline="always")
def _key_row(dst, bits, idf, start):
    """dst[i] = key of pixel start + i: (depth bits << 32) | id, or no key."""
    n = dst.shape[0]
    b = bits[2 * start:2 * (start + n)]
    q = idf[start:start + n]
    for i in range(n):
        key = (np.int64(b[2 * i]) << 32) | (q[i] & 0xFFFFFFFF)
        dst[i] = key if q[i] >= 0 else _NO_KEY


@njit(cache=True, inline="always")
def _min_into(acc, values):
    for i in range(acc.shape[0]):
        v = values[i]
        acc[i] = v if v < acc[i] else acc[i]


