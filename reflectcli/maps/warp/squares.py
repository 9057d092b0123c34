"""Splats zexel by zexel over squares: adaptive radii (from the warp's local footprint)
and ordered wide splats. One band of screen rows per task (each band visits every run but
skips the map rows that cannot reach it), so results do not depend on the thread count."""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

from .visibility import SAME_SURFACE


def splat_radii(sx, sy, z, shape, mode, out: np.ndarray | None = None) -> np.ndarray:
    """Per-zexel splat radius: fixed (1 -> 0, 3 -> 1, 5 -> 2) or adaptive from the warp's
    local footprint (half the screen distance to the right and lower neighbours, within a
    surface: neighbours more than 5% apart in depth do not count), capped at 3.
    `out`: an int8 array to write adaptive radii into."""
    if mode != "adaptive":
        return np.full(sx.shape[0], (int(mode) - 1) // 2, np.int8)
    radii = np.empty(sx.shape[0], np.int8) if out is None else out
    _adaptive(sx, sy, z, shape[0], shape[1], radii)
    return radii


@njit(cache=True, parallel=True)
def _adaptive(sx, sy, z, mh, mw, radii):
    for v in prange(mh):
        for u in range(mw):
            k = v * mw + u
            radii[k] = 0
            if np.isnan(sx[k]):
                continue
            reach = 0.0
            for du, dv in ((1, 0), (0, 1), (-1, 0), (0, -1)):
                uu, vv = u + du, v + dv
                if uu < 0 or vv < 0 or uu >= mw or vv >= mh:
                    continue
                q = vv * mw + uu
                if np.isnan(sx[q]):
                    continue
                if not (abs(z[q] - z[k]) <= 0.05 * min(z[q], z[k])):
                    continue
                reach = max(reach, abs(sx[q] - sx[k]), abs(sy[q] - sy[k]))
            radii[k] = min(3, int(math.ceil(reach * 0.5 - 0.5))) if reach > 1.0 else 0


def splat(sx, sy, z, radii, runs, mw, row_lo, row_hi, slot, stride, stencil, best_zd, best_id,
          ordered: bool, bands: int | None = None, rows: np.ndarray | None = None) -> None:
    """Write the zexels, visited run by run, into the per-pixel buffers over `stencil`:
    best_zd (H, W, 2) float32 (front depth, squared distance of the kept zexel to the pixel
    center) and best_id; ids are slot * stride + zexel index. `row_lo`/`row_hi`: per map row, the
    screen rows its zexels land on (splats add their radius).

    One band of screen rows per task: each band visits every run but skips the map rows
    that cannot reach it, so the work per band stays close to the zexels that land in it,
    and the result does not depend on the thread count. `bands`: how many (default: two a
    thread). `rows`: the stencil's rows that hold a pixel, if the caller has them."""
    if rows is None:
        rows = np.flatnonzero(stencil.any(axis=1))
    if rows.size == 0:
        return
    reach = int(radii.max()) if radii.size else 0
    if bands is None:
        bands = max(1, numba.get_num_threads()) * 2
    edges = np.linspace(rows[0], rows[-1] + 1, bands + 1).round().astype(np.int64)
    _splat(sx, sy, z, radii, runs, mw, row_lo - reach, row_hi + reach, slot, stride, stencil,
           best_zd, best_id, edges, ordered)


@njit(cache=True, parallel=True)
def _splat(sx, sy, z, radii, runs, mw, row_lo, row_hi, slot, stride, stencil, best_zd, best_id,
           edges, ordered):
    width = stencil.shape[1]
    for b in prange(edges.shape[0] - 1):
        row0 = edges[b]
        row1 = edges[b + 1]
        for run in range(runs.shape[0]):
            v = runs[run, 0]
            if row_hi[v] < row0 or row_lo[v] >= row1:
                continue
            for u in range(runs[run, 1], runs[run, 2], runs[run, 3]):
                k = v * mw + u
                if np.isnan(sx[k]):
                    continue
                py = int(math.floor(sy[k]))
                r = radii[k]
                if py + r < row0 or py - r >= row1:
                    continue
                fx = sx[k]
                fy = sy[k]
                px = int(math.floor(fx))
                zk = z[k]
                ident = slot * stride + k
                if r == 0:  # one pixel: the common case, without the loops
                    if 0 <= px < width and stencil[py, px]:
                        dk = (fx - px - 0.5) ** 2 + (fy - py - 0.5) ** 2
                        _write(py, px, zk, dk, ident, slot, stride, best_zd, best_id,
                               ordered)
                    continue
                for y in range(max(py - r, row0), min(py + r, row1 - 1) + 1):
                    for x in range(max(px - r, 0), min(px + r, width - 1) + 1):
                        if stencil[y, x]:
                            dk = (fx - x - 0.5) ** 2 + (fy - y - 0.5) ** 2
                            _write(y, x, zk, dk, ident, slot, stride, best_zd, best_id,
                                   ordered)


@njit(cache=True, inline="always")
def _write(y, x, zk, dk, ident, slot, stride, best_zd, best_id, ordered):
    """The visibility rule at one pixel, against the zexel kept so far (its eye depth in
    best_zd[..., 0], its squared distance to the pixel center in best_zd[..., 1]: one cache
    line). z-buffer: a zexel more than SAME_SURFACE nearer takes the pixel; one within
    SAME_SURFACE of it (the same surface) takes it if it lands nearer the center (ties to the
    lower id). So the kept zexel is never more than SAME_SURFACE behind any that arrived.
    Ordered mode: a zexel of the same map wins regardless (McMillan's order)."""
    current = best_id[y, x]
    bz = best_zd[y, x, 0]
    if current < 0 or zk < bz * (1.0 - SAME_SURFACE) or (
            ordered and current // stride == slot):
        best_zd[y, x, 0] = zk
        best_zd[y, x, 1] = dk
        best_id[y, x] = ident
    elif zk <= bz * (1.0 + SAME_SURFACE) or zk == bz:  # == for two zexels at infinity
        # selects, not branches: which zexel lands nearer the center is close to random
        bd = best_zd[y, x, 1]
        take = (dk < bd) | ((dk == bd) & (ident < current))
        best_zd[y, x, 0] = zk if take else bz
        best_zd[y, x, 1] = dk if take else bd
        best_id[y, x] = ident if take else current
