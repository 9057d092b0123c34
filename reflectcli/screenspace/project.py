"""Pixel-projected reflections (Cichocki, SIGGRAPH 2017 Advances; Far Cry 5), numba.

Projection pass, per planar mirror (n, d) turned toward the eye: every primary pixel that
shows an object point X in front of the plane (dist = n.X + d > 0) is mirrored,
X' = X - 2 dist n, and projected to the screen; if the target pixel shows this mirror, the
source claims it with the key (float32 bits of dist) << 32 | source pixel index. Per
target the smallest key wins: the point nearest the mirror plane (nearest along the
reflected ray, since all points on one reflected ray share its angle to the plane), ties
to the lower index. The paper packs an offset into a 32-bit atomic min; here the keys are
made in parallel and the min taken in one serial pass (a min is order-free, so the result
does not depend on the thread count either way; numba has no 64-bit atomics).

Reflection pass: a mirror pixel no source reached, lying between two reached pixels on
opposite sides (a one-pixel hole of the scatter), takes the smaller of their keys, read
from the unfilled buffer so the fill is order-free too.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

EMPTY = np.uint64(0xFFFFFFFFFFFFFFFF)


@njit(cache=True, parallel=True)
def project_sources(tri, b1, b2, surface_ids, n_objects, corners, plane, sid, clip_from_world,
                    targets, keys):
    """Per source pixel (row-major index): its target pixel index (or -1) and key."""
    h, w = tri.shape
    nx, ny, nz, d = plane[0], plane[1], plane[2], plane[3]
    m = clip_from_world
    for y in prange(h):
        for x in range(w):
            i = y * w + x
            targets[i] = -1
            keys[i] = EMPTY
            s = surface_ids[y, x]
            if s < 0 or s >= n_objects:
                continue
            t = tri[y, x]
            c1 = b1[y, x]
            c2 = b2[y, x]
            c0 = 1.0 - c1 - c2
            px = c0 * corners[t, 0, 0] + c1 * corners[t, 1, 0] + c2 * corners[t, 2, 0]
            py = c0 * corners[t, 0, 1] + c1 * corners[t, 1, 1] + c2 * corners[t, 2, 1]
            pz = c0 * corners[t, 0, 2] + c1 * corners[t, 1, 2] + c2 * corners[t, 2, 2]
            dist = nx * px + ny * py + nz * pz + d
            if not dist > 0.0:
                continue
            rx, ry, rz = px - 2.0 * dist * nx, py - 2.0 * dist * ny, pz - 2.0 * dist * nz
            cw = m[3, 0] * rx + m[3, 1] * ry + m[3, 2] * rz + m[3, 3]
            cz = m[2, 0] * rx + m[2, 1] * ry + m[2, 2] * rz + m[2, 3]
            if cz < -cw or cz > cw or cw <= 0.0:  # outside near / far
                continue
            cx = m[0, 0] * rx + m[0, 1] * ry + m[0, 2] * rz + m[0, 3]
            cy = m[1, 0] * rx + m[1, 1] * ry + m[1, 2] * rz + m[1, 3]
            sx = (cx / cw + 1.0) * 0.5 * w
            sy = (1.0 - cy / cw) * 0.5 * h
            if not (sx >= 0.0 and sy >= 0.0 and sx < w and sy < h):
                continue
            tx = int(sx)
            ty = int(sy)
            if surface_ids[ty, tx] != sid:
                continue
            bits = np.uint64(np.float32(dist).view(np.uint32))
            targets[i] = ty * w + tx
            keys[i] = (bits << np.uint64(32)) | np.uint64(i)


@njit(cache=True)
def scatter_min(targets, keys, buffer):
    """buffer[target] = min(buffer[target], key) over all sources; in place."""
    for i in range(targets.shape[0]):
        t = targets[i]
        if t >= 0 and keys[i] < buffer[t]:
            buffer[t] = keys[i]


@njit(cache=True)
def _key_at(buffer, surface_ids, s, w, h, x, y):
    """The key at (x, y) if it is a pixel of surface s, else EMPTY."""
    if y < 0 or x < 0 or y >= h or x >= w or surface_ids[y, x] != s:
        return EMPTY
    return buffer[y * w + x]


@njit(cache=True, parallel=True)
def fill_holes(buffer, surface_ids, n_objects, w, out, filled):
    """out = buffer, and each empty mirror pixel between two reached pixels of the same
    mirror on opposite sides (left and right, above and below, or across a diagonal) takes
    the smallest of their keys: one-pixel holes close, the border of the reflection does
    not grow. Reads only `buffer`, so the fill is order-free; `filled` marks those."""
    h = surface_ids.shape[0]
    for y in prange(h):
        for x in range(w):
            i = y * w + x
            out[i] = buffer[i]
            filled[y, x] = False
            s = surface_ids[y, x]
            if buffer[i] != EMPTY or s < n_objects:
                continue
            best = EMPTY
            for dx, dy in ((1, 0), (0, 1), (1, 1), (1, -1)):
                a = _key_at(buffer, surface_ids, s, w, h, x + dx, y + dy)
                b = _key_at(buffer, surface_ids, s, w, h, x - dx, y - dy)
                if a != EMPTY and b != EMPTY:
                    best = min(best, min(a, b))
            if best != EMPTY:
                out[i] = best
                filled[y, x] = True


@njit(cache=True, parallel=True)
def decode(buffer, w, rays, tri, b1, b2, corners, hit, hx, hy, dist):
    """Per target: hit, source pixel and the distance from the mirror point to the source.
    Every pixel written: one no source reached gets march.NO_HIT's (0, -1, -1, 0.0), what
    fresh new_outputs hold (march.outputs)."""
    h = hit.shape[0]
    mask = np.uint64(0xFFFFFFFF)
    for y in prange(h):
        for x in range(w):
            v = buffer[y * w + x]
            if v == EMPTY:
                hit[y, x] = 0
                hx[y, x] = -1
                hy[y, x] = -1
                dist[y, x] = 0.0
                continue
            src = int(v & mask)
            sy = src // w
            sx = src - sy * w
            hit[y, x] = 1
            hx[y, x] = sx
            hy[y, x] = sy
            t = tri[sy, sx]
            c1 = b1[sy, sx]
            c2 = b2[sy, sx]
            c0 = 1.0 - c1 - c2
            s2 = 0.0
            for a in range(3):
                p = c0 * corners[t, 0, a] + c1 * corners[t, 1, a] + c2 * corners[t, 2, a]
                e = p - rays[y, x, a]
                s2 += e * e
            dist[y, x] = np.sqrt(s2)
