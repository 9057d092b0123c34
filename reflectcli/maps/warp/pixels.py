"""The one-pixel splat: each zexel at the pixel it lands in, by the visibility rule.

It projects the map itself, row by row into buffers each task keeps in cache (no
projection arrays), one band of screen rows per task balanced by zexel count, and writes
each reached pixel's payload row (colour, triangle) as it goes, so no gather pass follows."""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

from .payload import _copy_row, _payload_args
from .projection import Projection, _project_row, _row_reach, screen_matrix
from .visibility import SAME_SURFACE


def splat_pixels(proj: Projection, runs, mw, base, stencil, best_zd, best_id, ordered: bool,
                 region, clear: bool, use_stencil: bool, bands: int | None = None,
                 payload=None, payload_out=None, source=None) -> int:
    """The one-pixel splat: each zexel of `proj` (visited run by run) at the pixel it lands
    in, by the visibility rule of `_write`, into best_zd (H, W, 2) float32 (depth, squared
    distance of the zexel to the pixel center) and best_id (ids base + zexel index), only
    inside `region` = (x0, x1, y0, y1) (and, with `use_stencil`, only on stencil pixels);
    `proj` must come from `project_map` with that region as its grown box (its columns are
    not checked again) and `positions=False` (the distances). `clear`: reset the region
    first (inside the kernel, each band its rows; a cleared pixel is (inf, inf), -1, which
    the rule reads as empty without looking at its id). One band of rows per task, balanced
    by zexel count; each band visits every run but skips the map rows that cannot reach it,
    so the result does not depend on the thread count. `bands`: how many (default: two a
    thread). `payload` (n, c): a row per zexel, copied into `payload_out` (H, W, c) with
    each zexel that takes a pixel (so a reached pixel ends with its kept zexel's row; other
    pixels are left alone). `source` = (depth (mh, mw), W, near, (x0, x1, y0, y1) the grown
    box): project the map inside the kernel instead (each task the rows that reach its band,
    into buffers it keeps in cache; the same arithmetic and results as `project_map` with
    that box and `positions=False`); proj's arrays then serve as scratch: row_lo / row_hi
    receive bounds of the screen rows each map row can reach (from its depths' range,
    without projecting it), count its zexels of usable depth. Returns how many zexels
    landed in the region (on the stencil or not)."""
    x0, x1, y0, y1 = region
    if bands is None:
        bands = max(1, numba.get_num_threads()) * 2
    h, w = best_id.shape
    pay, pay_out = _payload_args(payload, payload_out)
    if source is None:  # proj holds the projection
        from_depth, near, grown = False, 0.0, region
        depth, m = np.empty((1, 1), np.float32), np.empty((4, 4), np.float32)
    else:  # project here: proj receives only the rows' spans and counts
        depth, wm, near, grown = source
        from_depth = True
        depth = np.ascontiguousarray(depth, np.float32)
        m = np.ascontiguousarray(screen_matrix(w, h) @ wm, np.float32)
    return _splat_pixels(proj.pix, proj.d, proj.z, runs, mw, proj.row_lo, proj.row_hi, proj.count,
                         base, ordered, stencil.reshape(-1), use_stencil, x0, x1, y0, y1, w,
                         clear, bands, best_zd.reshape(-1), best_id.reshape(-1),
                         payload is not None, pay,
                         pay_out, from_depth, depth, m, near, grown[0], grown[1], grown[2],
                         grown[3], h)


@njit(cache=True, parallel=True, error_model="numpy")
def _splat_pixels(pix, dist, z, runs, mw, row_lo, row_hi, count, base, ordered, stencil,
                  use_stencil, x0, x1, y0, y1, width, clear, bands, zd, ids, with_payload, pay,
                  pay_out, from_depth, depth, m, near, xmin, xmax, ymin, ymax, height):
    # zd: (depth, squared distance) per pixel, one 8-byte record.
    # from_depth: project the map (depth, m: as `_project` with positions=False) here, row by
    # row into buffers each task keeps in cache, instead of reading pix, dist, z: each band
    # projects the rows that can reach it, by bounds on each row's screen rows (into row_lo,
    # row_hi; count: its zexels of usable depth, the bands' weights) taken from its depths.
    # Returns how many zexels landed in the region (stencil or not).
    depth_bits = depth.view(np.int32)
    if from_depth:  # each map row's reach, bounded from its depths without projecting it
        # (serial: 0.05 ms for 512 rows, less than a thread's wake-up on a busy machine; the
        # bands are then the kernel's one parallel loop)
        for v in range(row_lo.shape[0]):
            lo, hi, usable = _row_reach(depth_bits, m, v, ymin, ymax)
            row_lo[v] = lo if usable > 0 else 1 << 40
            row_hi[v] = hi if usable > 0 else -1
            count[v] = usable
    # band edges over rows [y0, y1): each map row's zexels counted at its middle row
    hist = np.zeros(y1 - y0 + 1, np.int64)
    total = 0
    for v in range(row_lo.shape[0]):
        if count[v] > 0:
            mid = min(max((row_lo[v] + row_hi[v]) // 2, y0), y1) - y0
            hist[mid] += count[v]
            total += count[v]
    edges = np.empty(bands + 1, np.int64)
    edges[0] = y0
    edges[bands] = y1
    acc = 0
    b = 1
    for y in range(y1 - y0):
        acc += hist[y]
        while b < bands and acc * bands >= total * b:
            edges[b] = y0 + y + 1
            b += 1
    while b < bands:
        edges[b] = y1
        b += 1
    inf = np.float32(np.inf)
    landed = np.zeros(bands, np.int64)
    for b in prange(bands):
        r0 = edges[b]
        r1 = edges[b + 1]
        if r1 <= r0:
            continue
        n_landed = 0
        if clear:
            for y in range(r0, r1):
                for p in range(y * width + x0, y * width + x1):
                    zd[2 * p] = inf
                    zd[2 * p + 1] = inf  # no zexel lands this far from a center: empty
                    ids[p] = -1
        p0 = r0 * width
        p1 = r1 * width
        bp = np.empty(mw, np.int32)
        bz = np.empty(mw, np.float32)
        bd = np.empty(mw, np.float32)
        projected = -1
        for run in range(runs.shape[0]):
            v = runs[run, 0]
            if row_hi[v] < r0 or row_lo[v] >= r1:
                continue
            if from_depth:
                if v != projected:
                    _project_row(depth, m, v, near, xmin, xmax, ymin, ymax, width, height,
                                 False, bd, bd, bz, bp, bd)
                    projected = v
                rp, rz, rd = bp, bz, bd
            else:
                rp = pix[v * mw:(v + 1) * mw]
                rz = z[v * mw:(v + 1) * mw]
                rd = dist[v * mw:(v + 1) * mw]
            n_landed += _scatter_run(rp, rz, rd, runs[run, 1], runs[run, 2], runs[run, 3],
                                     v * mw, base, p0, p1, ordered, use_stencil, stencil, zd,
                                     ids, with_payload, pay, pay_out)
        landed[b] = n_landed
    return landed.sum()




@njit(cache=True, error_model="numpy")
def _scatter_run(rp, rz, rd, first, stop, step, k0, base, p0, p1, ordered, use_stencil, stencil,
                 zd, ids, with_payload, pay, pay_out):
    """One run of a projected map row (pixel, depth, squared distance per column: rp, rz,
    rd; zexel index k0 + column) into the pixels [p0, p1) by the visibility rule; returns
    how many landed there. A function of its own (not inlined into the band loop): in the
    band loop's body the rule's values did not fit the registers and spilled. Pixel
    indices are unsigned once checked (no negative-index wraparound)."""
    landed = 0
    span = np.uint64(p1 - p0)
    for u in range(first, stop, step):
        p = np.uint64(np.int64(rp[u]) - p0)
        if p >= span:  # also rp = -1: not warped
            continue
        p += np.uint64(p0)
        landed += 1
        if use_stencil and not stencil[p]:
            continue
        dk = rd[u]
        zk = rz[u]
        k = k0 + u
        ident = base + k
        cz = zd[2 * p]
        # an empty pixel (inf, inf): a finite zk is nearer, an infinite one lands nearer
        # the center; its id is read only for an exact tie or in ordered mode
        take = zk < cz * (1.0 - SAME_SURFACE)
        if not take and ordered:
            take = ids[p] >= base
        if not take and (zk <= cz * (1.0 + SAME_SURFACE) or zk == cz):
            cd = zd[2 * p + 1]
            take = dk < cd
            if dk == cd:
                take = ident < ids[p]
        if take:
            zd[2 * p] = zk
            zd[2 * p + 1] = dk
            ids[p] = ident
            if with_payload:
                _copy_row(pay, k, pay_out, p)
    return landed
