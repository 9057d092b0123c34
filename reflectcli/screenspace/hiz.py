"""Hierarchical-Z traversal: a min-depth pyramid and a cell-by-cell march over it (numba).

Stachowiak 2015 (stochastic screen-space reflections) and AMD FidelityFX SSSR's mirror
path: level 0 is the depth buffer, each coarser level the minimum (nearest) eye depth of
2x2 cells (odd edges clamp). The ray walks in screen space with q = 1 / depth affine in the
parameter u; in a cell whose nearest depth the ray does not reach before leaving it, it
skips the cell and climbs a level; where it might reach it, it moves to that depth and
descends. At level 0 the pixel's segment of the ray [u_enter, u_exit] hits when its depth
range overlaps [s, s + thickness] (the same test as the brute-force pixel walk in
tests/naive_screenspace.py); a segment wholly behind by more than `thickness` is passed at
level 0. The loop counts one lookup per cell visited.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

from ..parallel import claim_rows, counter
from ..raster.rasterize.buffers import scratch
from .march import NO_HIT, _store_march
from .rays import distance_at

MAX_LEVELS = 16
PYRAMID = "hiz_pyramid"  # build_pyramid's array in a workspace


def build_pyramid(depth: np.ndarray, workspace=None) -> tuple[np.ndarray, np.ndarray]:
    """(flat float32 pyramid, (L, 3) int64 rows of offset, width, height). `workspace`:
    the pyramid is its array, kept from frame to frame (valid until the next call); _build
    writes every cell of every level, so nothing an earlier frame left is read."""
    h, w = depth.shape
    dims = [(w, h)]
    while (dims[-1][0] > 1 or dims[-1][1] > 1) and len(dims) < MAX_LEVELS:
        pw, ph = dims[-1]
        dims.append(((pw + 1) // 2, (ph + 1) // 2))
    table = np.zeros((len(dims), 3), np.int64)
    offset = 0
    for i, (lw, lh) in enumerate(dims):
        table[i] = offset, lw, lh
        offset += lw * lh
    flat = scratch(workspace, PYRAMID, (offset,), np.float32)
    _build(np.ascontiguousarray(depth, np.float32), flat, table)
    return flat, table


@njit(cache=True)
def _build(depth, flat, table):
    h, w = depth.shape
    for y in range(h):
        for x in range(w):
            flat[y * w + x] = depth[y, x]
    for lv in range(1, table.shape[0]):
        po, pw, ph = table[lv - 1, 0], table[lv - 1, 1], table[lv - 1, 2]
        o, lw, lh = table[lv, 0], table[lv, 1], table[lv, 2]
        for y in range(lh):
            for x in range(lw):
                m = np.inf
                for j in range(2):
                    yy = min(2 * y + j, ph - 1)
                    for i in range(2):
                        xx = min(2 * x + i, pw - 1)
                        v = flat[po + yy * pw + xx]
                        if v < m:
                            m = v
                flat[o + y * lw + x] = m


@njit(cache=True)
def _exit_u(x0, y0, dx, dy, cx, cy, size):
    """Screen parameter u where the ray leaves the cell (cx, cy) of `size` pixels."""
    ux = np.inf
    uy = np.inf
    if dx > 0.0:
        ux = ((cx + 1) * size - x0) / dx
    elif dx < 0.0:
        ux = (cx * size - x0) / dx
    if dy > 0.0:
        uy = ((cy + 1) * size - y0) / dy
    elif dy < 0.0:
        uy = (cy * size - y0) / dy
    return min(ux, uy)


@njit(cache=True)
def pixel_overlap(q0, dq, u_in, u_out, s, thickness):
    """(hit, u of the hit) for the ray's segment [u_in, u_out] over a pixel of depth s."""
    qa = q0 + dq * u_in
    qb = q0 + dq * u_out
    da = 1.0 / qa
    db = 1.0 / qb if qb > 0.0 else np.inf
    lo = min(da, db)
    hi = max(da, db)
    if hi >= s and lo <= s + thickness:
        if da >= s:
            return True, u_in
        return True, (1.0 / s - q0) / dq  # crosses the front surface inside the pixel
    return False, u_in


@njit(cache=True)
def march_hiz(r, flat, table, surface_ids, own, thickness, max_steps):
    """(hit, hx, hy, distance, gap, lookups) of one ray over the pyramid."""
    h = table[0, 2]
    w = table[0, 1]
    levels = table.shape[0]
    x0, y0, q0, x1, y1, q1 = r[14], r[15], r[16], r[17], r[18], r[19]
    dx = x1 - x0
    dy = y1 - y0
    dq = q1 - q0
    major = max(abs(dx), abs(dy))
    if major < 1e-6:
        return 0, -1, -1, 0.0, 0.0, 0
    eps = 1e-4 / major  # a ten-thousandth of a pixel, in u
    # start past the origin's own pixel
    u = _exit_u(x0, y0, dx, dy, int(x0), int(y0), 1) + eps
    level = 0
    lookups = 0
    while lookups < max_steps:
        if u > 1.0:
            break
        x = x0 + dx * u
        y = y0 + dy * u
        if not (x >= 0.0 and y >= 0.0 and x < w and y < h):
            break
        size = 1 << level
        cx = int(x) >> level
        cy = int(y) >> level
        o, lw = table[level, 0], table[level, 1]
        m = flat[o + cy * lw + cx]
        lookups += 1
        u_exit = min(_exit_u(x0, y0, dx, dy, cx, cy, size), 1.0)
        q = q0 + dq * u
        if level == 0:
            hit, uh = pixel_overlap(q0, dq, u, u_exit, m, thickness)
            if hit and surface_ids[cy, cx] != own:
                return 1, cx, cy, distance_at(r, uh), 1.0 / (q0 + dq * uh) - m, lookups
            in_front = 1.0 / q < m and 1.0 / (q0 + dq * u_exit) < m
            u = u_exit + eps
            if in_front and level + 1 < levels:
                level += 1
            continue
        if 1.0 / q >= m:  # already at or behind the cell's nearest depth: look closer
            level -= 1
            continue
        if dq < 0.0:  # moving away from the camera: where does it reach the nearest depth?
            u_s = (1.0 / m - q0) / dq
            if u_s < u_exit:
                if u_s > u:
                    u = u_s
                level -= 1
                continue
        u = u_exit + eps
        if level + 1 < levels:
            level += 1
    return 0, -1, -1, 0.0, 0.0, lookups


def march_hiz_all(rays, valid, flat, table, surface_ids, thickness, max_steps,
                  hit, hx, hy, dist, gap, lookups) -> None:
    """march_hiz for every valid pixel, into the output arrays (in place); the other
    pixels get NO_HIT (every pixel written: march.outputs)."""
    _march_hiz_all(rays, valid, flat, table, surface_ids, thickness, max_steps,
                   hit, hx, hy, dist, gap, lookups, numba.get_num_threads())


@njit(cache=True, parallel=True)
def _march_hiz_all(rays, valid, flat, table, surface_ids, thickness, max_steps,
                   hit, hx, hy, dist, gap, lookups, threads):
    """Every valid pixel's ray; bands of rows claimed by whichever thread is free (a
    mirror's pixels bunch in some rows; a pixel's result is its own whoever marches it)."""
    h, w = valid.shape
    claimed = counter()
    for _worker in prange(threads):
        y0, y1 = claim_rows(claimed, h)
        while y0 < y1:
            for y in range(y0, y1):
                for x in range(w):
                    if valid[y, x]:
                        _store_march(march_hiz(rays[y, x], flat, table, surface_ids,
                                              surface_ids[y, x], thickness, max_steps),
                                    y, x, hit, hx, hy, dist, gap, lookups)
                    else:  # every pixel written (march.outputs)
                        _store_march(NO_HIT, y, x, hit, hx, hy, dist, gap, lookups)
            y0, y1 = claim_rows(claimed, h)
