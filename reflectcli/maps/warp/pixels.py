"""The one-pixel splat: each zexel at the pixel it lands in, by the visibility rule.

It projects the map itself, row by row into buffers each task keeps in cache (no
projection arrays), in bands of screen rows of about equal landings, one a task, and
writes each reached pixel's payload row (colour, triangle) as it goes, so no gather pass
follows."""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

from ...prefetch import prefetch_write
from .payload import _payload_flat
from .projection import Projection, _project_row, _row_reach, screen_matrix_cached
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
    first (inside the kernel, each band its rows, as its runs come to them; a cleared pixel
    is (inf, inf), -1, which the rule reads as empty without looking at its id). Bands of
    rows of about equal landings (each map row's zexels spread over the screen rows they
    reach), one a task; each band visits every run but skips the map rows that cannot reach
    it, so the result does not depend on the thread count. `bands`: how many (default: two a
    thread). A band whose stencil rows are all set skips the stencil test. `runs` step by
    one column (+1 or -1). `payload` (n, c): a row per zexel, copied into `payload_out` (H,
    W, c) with each zexel that takes a pixel (so a reached pixel ends with its kept zexel's
    row; other pixels are left alone). `source` = (depth (mh, mw), W, near, (x0, x1, y0, y1)
    the grown box): project the map inside the kernel instead (each task the rows that reach
    its band, into buffers it keeps in cache; the same arithmetic and results as
    `project_map` with that box and `positions=False`); proj's arrays then serve as scratch:
    row_lo / row_hi receive bounds of the screen rows each map row can reach (from its
    depths' range, without projecting it), count its zexels of usable depth. Returns how
    many zexels landed in the region (on the stencil or not)."""
    x0, x1, y0, y1 = region
    if bands is None:
        bands = max(1, numba.get_num_threads()) * 2
    h, w = best_id.shape
    pay, pay_out, width = _payload_flat(payload, payload_out)
    if source is None:  # proj holds the projection
        from_depth, near, grown = False, 0.0, region
        depth, m = np.empty((1, 1), np.float32), np.empty((4, 4), np.float32)
    else:  # project here: proj receives only the rows' spans and counts
        depth, wm, near, grown = source
        from_depth = True
        depth = np.ascontiguousarray(depth, np.float32)
        m = (screen_matrix_cached(w, h) @ wm).astype(np.float32)
    return _splat_pixels(proj.pix, proj.d, proj.z, runs, mw, proj.row_lo, proj.row_hi, proj.count,
                         base, ordered, stencil.reshape(-1), use_stencil, x0, x1, y0, y1, w,
                         clear, bands, best_zd.reshape(-1), best_id.reshape(-1), width, pay,
                         pay_out, from_depth, depth, m, near, grown[0], grown[1], grown[2],
                         grown[3], h)


@njit(cache=True, parallel=True, error_model="numpy")
def _splat_pixels(pix, dist, z, runs, mw, row_lo, row_hi, count, base, ordered, stencil,
                  use_stencil, x0, x1, y0, y1, width, clear, bands, zd, ids, pay_width, pay,
                  pay_out, from_depth, depth, m, near, xmin, xmax, ymin, ymax, height):
    # zd: (depth, squared distance) per pixel, one 8-byte record.
    # from_depth: project the map (depth, m: as `_project` with positions=False) here, row by
    # row into buffers each task keeps in cache, instead of reading pix, dist, z: each band
    # projects the rows that can reach it, by bounds on each row's screen rows (into row_lo,
    # row_hi; count: its zexels of usable depth) taken from its depths.
    # pay, pay_out: payload rows flat (zexel k's row at pay_width * k, pixel p's at
    # pay_width * p); pay_width 0: none.
    # Returns how many zexels landed in the region (stencil or not).
    n_rows = row_lo.shape[0]
    stencil_bytes = stencil.view(np.uint8)
    if from_depth:  # each map row's reach, bounded from its depths without projecting it
        first, last = _reaches(depth.view(np.int32), m, ymin, ymax, row_lo, row_hi, count)
    else:  # the projection's rows are exact
        first, last = row_lo, row_hi
    # band weights over rows [y0, y1): a map row's zexels spread evenly over the screen rows
    # they reach (a difference array of zexels a row; those beyond [y0, y1) weigh nothing)
    # (no array expressions here, np.zeros or .sum(): in a parallel kernel each becomes a
    # parallel region of its own, and with OpenMP on a busy machine every region can wait
    # for a worker that lost its core; the bands are the kernel's one parallel loop)
    rate = np.empty(y1 - y0 + 1, np.float64)
    for y in range(y1 - y0 + 1):
        rate[y] = 0.0
    for v in range(n_rows):
        a = max(first[v], y0)
        b = min(last[v], y1 - 1)
        if count[v] > 0 and a <= b:
            per = count[v] / (last[v] - first[v] + 1)
            rate[a - y0] += per
            rate[b - y0 + 1] -= per
    weight = np.empty(y1 - y0, np.float64)
    running = 0.0
    total = 0.0
    for y in range(y1 - y0):
        running += rate[y]
        weight[y] = running
        total += running
    edges = np.empty(bands + 1, np.int64)
    edges[0] = y0
    edges[bands] = y1
    acc = 0.0
    k = 1
    for y in range(y1 - y0):
        acc += weight[y]
        while k < bands and acc * bands >= total * k:
            edges[k] = y0 + y + 1
            k += 1
    while k < bands:
        edges[k] = y1
        k += 1
    landed = np.empty(bands, np.int64)
    # one band a task (numba's OpenMP layer gives each thread a fixed share of them: with
    # bands of about equal landings the shares balance)
    for b in prange(bands):
        bp = np.empty(mw, np.int32)
        bz = np.empty(mw, np.float32)
        bd = np.empty(mw, np.float32)
        r0 = edges[b]
        r1 = edges[b + 1]
        landed[b] = 0
        if r1 <= r0:
            continue
        n_landed = 0
        # the band's rows are readied as the runs come to them (rows [c0, c1), grown to each
        # run's rows before it writes there): cleared (the rest after the last run) and
        # their payload rows prefetched, so the scatter writes into rows still in cache
        # (cleared all first, a band's rows had left the cache before the scatter came)
        c0 = r0
        c1 = r0
        # a band whose rows of the stencil are all set (a mirror seen whole and
        # unoccluded) needs no test
        test = use_stencil and not _all_set(stencil_bytes, r0, r1, x0, x1, width)
        p0 = r0 * width
        p1 = r1 * width
        projected = -1
        for run in range(runs.shape[0]):
            v = runs[run, 0]
            if row_hi[v] < r0 or row_lo[v] >= r1:
                continue
            # (row_lo, row_hi: bounds of the rows the run can write)
            a = max(row_lo[v], r0)
            e = min(row_hi[v] + 1, r1)
            if c0 == c1:
                c0 = a
                c1 = a
            if a < c0:
                _ready_rows(zd, ids, a, c0, x0, x1, width, clear, pay_width, pay_out)
                c0 = a
            if e > c1:
                _ready_rows(zd, ids, c1, e, x0, x1, width, clear, pay_width, pay_out)
                c1 = e
            if v != projected:  # the row into the task's buffers
                if from_depth:
                    _project_row(depth, m, v, near, xmin, xmax, ymin, ymax, width, height,
                                 False, bd, bd, bz, bp, bd)
                else:
                    bp[:] = pix[v * mw:(v + 1) * mw]
                    bz[:] = z[v * mw:(v + 1) * mw]
                    bd[:] = dist[v * mw:(v + 1) * mw]
                projected = v
            # the step as a constant (runs go one column at a time): the scatter's loop
            # then compiles for it (a fifth faster than for a step known only at run time)
            if runs[run, 3] == 1:
                n_landed += _scatter_width(bp, bz, bd, runs[run, 1], runs[run, 2], 1, v * mw,
                                           base, p0, p1, ordered, test, stencil, zd, ids,
                                           pay_width, pay, pay_out)
            else:
                n_landed += _scatter_width(bp, bz, bd, runs[run, 1], runs[run, 2], -1, v * mw,
                                           base, p0, p1, ordered, test, stencil, zd, ids,
                                           pay_width, pay, pay_out)
        if clear:  # the rows no run reached
            if c0 == c1:
                c0 = r1
                c1 = r1
            _clear_rows(zd, ids, r0, c0, x0, x1, width)
            _clear_rows(zd, ids, c1, r1, x0, x1, width)
        landed[b] = n_landed
    n_landed = 0
    for b in range(bands):
        n_landed += landed[b]
    return n_landed


@njit(cache=True, inline="always", error_model="numpy")
def _ready_rows(zd, ids, ya, yb, x0, x1, width, clear, pay_width, pay_out):
    """Rows [ya, yb) about to be written: cleared (with `clear`), and their payload rows
    asked of memory (a prefetch a cache line: the scatter's stores then find them)."""
    if clear:
        _clear_rows(zd, ids, ya, yb, x0, x1, width)
    if pay_width > 0:
        line = max(1, 64 // pay_out.itemsize)  # values a cache line
        for y in range(ya, yb):
            for i in range(pay_width * (y * width + x0), pay_width * (y * width + x1), line):
                prefetch_write(pay_out, i)


@njit(cache=True, inline="always", error_model="numpy")
def _clear_rows(zd, ids, ya, yb, x0, x1, width):
    """Rows [ya, yb), columns [x0, x1) to no zexel: (inf, inf), -1. Rows as views indexed
    from 0: the loops vectorize (with indices that could be negative they did not: 2.5
    times as long)."""
    inf = np.float32(np.inf)
    for y in range(ya, yb):
        zd_row = zd[2 * (y * width + x0):2 * (y * width + x1)]
        for i in range(zd_row.shape[0]):
            zd_row[i] = inf  # depth and distance: no zexel lands this far off
        id_row = ids[y * width + x0:y * width + x1]
        for i in range(id_row.shape[0]):
            id_row[i] = -1


@njit(cache=True, error_model="numpy")
def _all_set(stencil_bytes, r0, r1, x0, x1, width) -> bool:
    """Every stencil pixel of rows [r0, r1), columns [x0, x1) is set (`stencil_bytes`: the
    flat stencil as 0/1 bytes). Counted a row at a time through views indexed from 0, in a
    function of its own: so the loop vectorizes (in the band loop it did not, and took
    0.1 ms for a whole screen)."""
    set_count = 0
    for y in range(r0, r1):
        on_row = stencil_bytes[y * width + x0:y * width + x1]
        row_count = np.uint32(0)
        for i in range(on_row.shape[0]):
            row_count += np.uint32(on_row[i])
        set_count += row_count
    return set_count == (r1 - r0) * (x1 - x0)


@njit(cache=True, inline="always", error_model="numpy")
def _reaches(depth_bits, m, ymin, ymax, row_lo, row_hi, count):
    """`_row_reach` of every map row into row_lo, row_hi (1 << 40, -1: no usable zexel) and
    count; returns the rows their zexels spread over (first, last). Serial (0.05 ms for 512
    rows): a parallel loop of its own would be a second parallel region a call, and with
    OpenMP on a busy machine each region can wait for a worker that lost its core."""
    n_rows = row_lo.shape[0]
    first = np.empty(n_rows, np.int64)
    last = np.empty(n_rows, np.int64)
    for v in range(n_rows):
        lo, hi, usable, f, la = _row_reach(depth_bits, m, v, ymin, ymax)
        row_lo[v] = lo if usable > 0 else 1 << 40
        row_hi[v] = hi if usable > 0 else -1
        count[v] = usable
        first[v] = f
        last[v] = la
    return first, last


@njit(cache=True, inline="always", error_model="numpy")
def _scatter_width(rp, rz, rd, first, stop, step, k0, base, p0, p1, ordered, use_stencil,
                   stencil, zd, ids, pay_width, pay, pay_out):
    """`_scatter_run` with the payload width as a constant where it is a common one (0: no
    payload, 3: colour, 4: colour and triangle): a constant argument compiles a scatter of
    its own, whose payload copy is straight-line stores (and with 0, no payload code)."""
    if pay_width == 0:
        return _scatter_run(rp, rz, rd, first, stop, step, k0, base, p0, p1, ordered,
                            use_stencil, stencil, zd, ids, 0, pay, pay_out)
    if pay_width == 3:
        return _scatter_run(rp, rz, rd, first, stop, step, k0, base, p0, p1, ordered,
                            use_stencil, stencil, zd, ids, 3, pay, pay_out)
    if pay_width == 4:
        return _scatter_run(rp, rz, rd, first, stop, step, k0, base, p0, p1, ordered,
                            use_stencil, stencil, zd, ids, 4, pay, pay_out)
    return _scatter_run(rp, rz, rd, first, stop, step, k0, base, p0, p1, ordered,
                        use_stencil, stencil, zd, ids, pay_width, pay, pay_out)


@njit(cache=True, error_model="numpy")
def _scatter_run(rp, rz, rd, first, stop, step, k0, base, p0, p1, ordered, use_stencil, stencil,
                 zd, ids, pay_width, pay, pay_out):
    """One run of a projected map row (pixel, depth, squared distance per column: rp, rz,
    rd; zexel index k0 + column) into the pixels [p0, p1) by the visibility rule; returns
    how many landed there. A function of its own (not inlined into the band loop): in the
    band loop's body the rule's values did not fit the registers and spilled. A loop of
    its own for each of `ordered` and `use_stencil` (constants in `_scatter_loop`): with
    them as values the loop kept both tests and more values than registers."""
    if ordered:
        if use_stencil:
            return _scatter_loop(rp, rz, rd, first, stop, step, k0, base, p0, p1, True, True,
                                 stencil, zd, ids, pay_width, pay, pay_out)
        return _scatter_loop(rp, rz, rd, first, stop, step, k0, base, p0, p1, True, False,
                             stencil, zd, ids, pay_width, pay, pay_out)
    if use_stencil:
        return _scatter_loop(rp, rz, rd, first, stop, step, k0, base, p0, p1, False, True,
                             stencil, zd, ids, pay_width, pay, pay_out)
    return _scatter_loop(rp, rz, rd, first, stop, step, k0, base, p0, p1, False, False,
                         stencil, zd, ids, pay_width, pay, pay_out)


@njit(cache=True, inline="always", error_model="numpy")
def _scatter_loop(rp, rz, rd, first, stop, step, k0, base, p0, p1, ordered, use_stencil,
                  stencil, zd, ids, pay_width, pay, pay_out):
    """`_scatter_run`'s loop. Pixel indices are unsigned once checked (no negative-index
    wraparound). A zexel that takes its pixel copies its payload row (flat `pay`,
    `pay_width` values a row) to the pixel's in `pay_out`."""
    landed = 0
    span = np.uint64(p1 - p0)
    one = np.uint64(1)
    two = np.uint64(2)
    c = np.uint64(pay_width)
    first_id = base + k0  # the id of column 0
    for col in range(first, stop, step):
        u = np.uint64(col)  # (columns are never negative: no wraparound)
        p = np.uint64(np.int64(rp[u]) - p0)
        if p >= span:  # also rp = -1: not warped
            continue
        p += np.uint64(p0)
        landed += 1
        if use_stencil and not stencil[p]:
            continue
        dk = rd[u]
        zk = rz[u]
        ident = first_id + col
        cz = zd[two * p]
        # an empty pixel (inf, inf): a finite zk is nearer, an infinite one lands nearer
        # the center; its id is read only for an exact tie or in ordered mode
        take = zk < cz * (1.0 - SAME_SURFACE)
        if not take and ordered:
            take = ids[p] >= base
        if not take and (zk <= cz * (1.0 + SAME_SURFACE) or zk == cz):
            cd = zd[two * p + one]
            take = dk < cd
            if dk == cd:
                take = ident < ids[p]
        if take:
            zd[two * p] = zk
            zd[two * p + one] = dk
            ids[p] = ident
            if pay_width > 0:  # the row, flat (a constant width: straight-line stores)
                src = c * (np.uint64(k0) + u)
                dst = c * p
                for j in range(pay_width):
                    pay_out[dst + np.uint64(j)] = pay[src + np.uint64(j)]
    return landed
