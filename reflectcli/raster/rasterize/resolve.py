"""Merging the threads' buffers into one: greatest key, then lowest triangle index (so the
bytes never depend on who drew what), and keys turned into eye depths."""

import numpy as np
from numba import njit, prange

from ...scene.types import MIRROR_TIE
from .constants import FLAG_MIRROR


@njit(cache=True, parallel=True, error_model="numpy")
def _resolve(flags, col0, col1, top, bottom, own_tri, own_key, drew, tri, depth, clear):
    """Merge the threads' buffers (greatest key, then lowest triangle index) into `tri`, and
    eye depth w = 1 / (1/w) from the key (a mirror's divided by MIRROR_TIE); buffers of
    threads that drew nothing (`drew`) are left out. Pixels outside the box [top, bottom)
    x [col0, col1) get no triangle; unless `clear` is False: then they keep what they held
    (only the box's rows are visited). Each row goes in passes without branches (they
    vectorise): the first drawing thread's buffers, the others' merged in, then the keys
    (kept in `depth` meanwhile) turned to depths."""
    h, w = tri.shape
    owners = np.flatnonzero(drew)
    # the rows and columns this call writes: the image, or (clear False) the box
    r0, r1 = (0, h) if clear else (max(top, 0), min(bottom, h))
    lo, hi = (0, w) if clear else (col0, col1)
    for py in prange(r0, r1):
        resolve_row(flags, py, col0, col1, top, bottom, lo, hi, owners, own_tri, own_key,
                    tri, depth)


@njit(cache=True, inline="always", error_model="numpy")
def resolve_row(flags, py, col0, col1, top, bottom, lo, hi, owners, own_tri, own_key, tri,
                depth):
    """Row py of `_resolve`: columns lo..hi-1 outside the box [col0, col1) (or the whole
    row, outside the box's rows [top, bottom)) get no triangle; inside, the merged
    triangle and its eye depth."""
    w = tri.shape[1]
    inside = top <= py < bottom and owners.size > 0
    first, last = (col0, col1) if inside else (w, w)
    for px in range(lo, min(first, hi)):
        tri[py, px] = -1
        depth[py, px] = np.inf
    for px in range(max(last, lo), hi):
        tri[py, px] = -1
        depth[py, px] = np.inf
    if not inside:
        return
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
