"""Ray marches over the depth buffer: `linear` (fixed eye-space steps) and `dda`
(McGuire & Mara 2014, JCGT 3(4), perspective-correct DDA over pixels), numba.

A hit: the ray passes behind the front surface stored at a pixel but by no more than
`thickness` (eye-space depth units): ray depth in [s, s + thickness] where s = depth[pixel]
(reflect's depth buffer holds positive eye depth = -z; the paper's camera also looks down
-z, so its `rayZMax >= sceneZMax - zThickness` with negative z is `d_min <= s + thickness`
here, and `rayZMin <= sceneZMax` is `d_max >= s`). Background (+inf) never hits. A hit on
the ray's own mirror surface is ignored (a reflector does not see itself here).

Every kernel writes per pixel: hit (uint8), hit pixel x, y (int32), distance along the ray
(eye-space units), gap (ray depth - surface depth at the hit) and the number of depth lookups.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

from ..parallel import claim_rows, counter
from .rays import distance_at, to_screen

LINEAR, DDA, HIZ = 0, 1, 2


# a march's result where no ray is marched: what new_outputs holds
NO_HIT = (0, -1, -1, 0.0, 0.0, 0)
# the output arrays' names in a workspace kept across frames (outputs)
OUTPUTS = (("march_hit", np.uint8), ("march_hx", np.int32), ("march_hy", np.int32),
           ("march_dist", np.float32), ("march_gap", np.float32), ("march_lookups", np.int32))


def new_outputs(h: int, w: int):
    return (np.zeros((h, w), np.uint8), np.full((h, w), -1, np.int32),
            np.full((h, w), -1, np.int32), np.zeros((h, w), np.float32),
            np.zeros((h, w), np.float32), np.zeros((h, w), np.int32))


def outputs(h: int, w: int, workspace=None):
    """(hit, hx, hy, dist, gap, lookups) (H, W): new_outputs without a workspace, else the
    workspace's arrays, kept from frame to frame (valid until the next call) and holding
    what an earlier frame left: march_all, march_hiz_all and ppr's decode write every
    pixel of those they are given (NO_HIT where no ray is marched or no source reached),
    so after them the arrays hold exactly what fresh new_outputs would."""
    if workspace is None:
        return new_outputs(h, w)
    return tuple(workspace.get(name, (h, w), dtype) for name, dtype in OUTPUTS)


@njit(cache=True)
def jitter_offset(x, y):
    """A fixed per-pixel number in [0, 1) (integer hash; no random state, so deterministic)."""
    v = (x * 73856093) ^ (y * 19349663)
    v = (v ^ (v >> 13)) * 1274126177
    v = v ^ (v >> 16)
    return (v & 0xFFFF) / 65536.0


# ---------------------------------------------------------------------------- linear


@njit(cache=True)
def march_linear(r, depth, surface_ids, own, thickness, steps, p00, p11):
    """(hit, hx, hy, distance, gap, lookups): `steps` equal eye-space steps along the ray,
    each projected to its pixel; on a hit, 8 bisections between the last two steps."""
    h, w = depth.shape
    ox, oy, oz, dx, dy, dz, length = r[6], r[7], r[8], r[9], r[10], r[11], r[13]
    step = length / steps
    lookups = 0
    for i in range(1, steps + 1):
        t = i * step
        sx, sy, q = to_screen(ox + dx * t, oy + dy * t, oz + dz * t, p00, p11, w, h)
        if not (sx >= 0.0 and sy >= 0.0 and sx < w and sy < h):
            break
        px = int(sx)
        py = int(sy)
        s = depth[py, px]
        lookups += 1
        d = 1.0 / q
        if d >= s and d <= s + thickness and surface_ids[py, px] != own:
            lo = t - step
            hi = t
            bx, by, bt, bd, bs = px, py, t, d, s
            for _ in range(8):
                mid = 0.5 * (lo + hi)
                mx, my, mq = to_screen(ox + dx * mid, oy + dy * mid, oz + dz * mid, p00, p11,
                                       w, h)
                cx = int(mx)
                cy = int(my)
                sm = depth[cy, cx]
                lookups += 1
                dm = 1.0 / mq
                if dm >= sm:
                    hi = mid
                    if dm <= sm + thickness and surface_ids[cy, cx] != own:
                        bx, by, bt, bd, bs = cx, cy, mid, dm, sm
                else:
                    lo = mid
            return 1, bx, by, bt, bd - bs, lookups
    return 0, -1, -1, 0.0, 0.0, lookups


# ---------------------------------------------------------------------------- dda


@njit(cache=True)
def march_dda(r, depth, surface_ids, own, thickness, stride, jitter, max_steps):
    """McGuire & Mara's traceScreenSpaceRay in reflect's conventions.

    Steps of `stride` pixels along the major screen axis from the pixel after the origin,
    the ray's depth range over each step taken half a step either side (their
    prevZMaxEstimate / rayZMax); `jitter` in [0, 1] shifts the start by up to one stride.
    On a hit with stride > 1, bisection between the previous and the hit step finds the
    first position behind the surface (at most log2(stride) + 2 lookups).
    """
    h, w = depth.shape
    x0, y0, q0, x1, y1, q1 = r[14], r[15], r[16], r[17], r[18], r[19]
    ddx = x1 - x0
    ddy = y1 - y0
    if ddx * ddx + ddy * ddy < 1e-4:  # degenerate: a ray along the view axis
        x1 += 0.01
        ddx = x1 - x0
    permute = abs(ddx) < abs(ddy)
    if permute:
        ddx, ddy = ddy, ddx
        a0, b0 = y0, x0
    else:
        a0, b0 = x0, y0
    step_dir = 1.0 if ddx > 0.0 else -1.0
    inv_dx = step_dir / ddx  # screen parameter u per pixel along the major axis
    db = ddy * inv_dx
    dq = (q1 - q0) * inv_dx
    du = inv_dx
    # the march position in pixels along the major axis from the origin
    n_major = abs(ddx)
    start = 1.0 + jitter * jitter_offset(int(x0), int(y0)) * stride
    lookups = 0
    prev_pos = 0.0
    pos = start
    prev_dmax = 1.0 / q0
    count = 0
    while pos <= n_major and count < max_steps:
        count += 1
        a = a0 + step_dir * pos
        b = b0 + db * pos
        q = q0 + dq * pos
        # depth over this step: from the previous estimate to half a stride ahead
        d_lo = prev_dmax
        q_half = q + dq * 0.5 * stride
        d_hi = 1.0 / q_half if q_half > 0.0 else np.inf
        prev_dmax = d_hi
        if d_lo > d_hi:
            d_lo, d_hi = d_hi, d_lo
        if permute:
            px, py = b, a
        else:
            px, py = a, b
        if not (px >= 0.0 and py >= 0.0 and px < w and py < h):
            break
        ix = int(px)
        iy = int(py)
        s = depth[iy, ix]
        lookups += 1
        if d_hi >= s and d_lo <= s + thickness and surface_ids[iy, ix] != own:
            bx, by, bpos, bgap = ix, iy, pos, (1.0 / q) - s
            if stride > 1.0:  # bisection between the previous step and this one
                lo = prev_pos
                hi = pos
                while hi - lo > 0.5:
                    mid = 0.5 * (lo + hi)
                    ma = a0 + step_dir * mid
                    mb = b0 + db * mid
                    mq = q0 + dq * mid
                    mx, my = (mb, ma) if permute else (ma, mb)
                    cx = int(mx)
                    cy = int(my)
                    sm = depth[cy, cx]
                    lookups += 1
                    dm = 1.0 / mq
                    if dm >= sm:
                        hi = mid
                        if dm <= sm + thickness and surface_ids[cy, cx] != own:
                            bx, by, bpos, bgap = cx, cy, mid, dm - sm
                    else:
                        lo = mid
            u = bpos * du
            return 1, bx, by, distance_at(r, min(u, 1.0)), bgap, lookups
        prev_pos = pos
        pos += stride
    return 0, -1, -1, 0.0, 0.0, lookups


def march_all(kind, rays, valid, depth, surface_ids, thickness, stride, jitter, max_steps,
              p00, p11, hit, hx, hy, dist, gap, lookups) -> None:
    """Run the `kind` march (LINEAR or DDA) for every valid pixel, into the output arrays;
    the other pixels get NO_HIT (every pixel written: `outputs`)."""
    _march_all(kind, rays, valid, depth, surface_ids, thickness, stride, jitter, max_steps,
               p00, p11, hit, hx, hy, dist, gap, lookups, numba.get_num_threads())


@njit(cache=True, parallel=True)
def _march_all(kind, rays, valid, depth, surface_ids, thickness, stride, jitter, max_steps,
               p00, p11, hit, hx, hy, dist, gap, lookups, threads):
    """march_all's kernel: bands of rows claimed by whichever thread is free (parallel.py; a
    pixel's result is its own)."""
    h, w = valid.shape
    claimed = counter()
    for _worker in prange(threads):
        y0, y1 = claim_rows(claimed, h)
        while y0 < y1:
            for y in range(y0, y1):
                for x in range(w):
                    if not valid[y, x]:  # every pixel written (outputs)
                        _store_march(NO_HIT, y, x, hit, hx, hy, dist, gap, lookups)
                        continue
                    own = surface_ids[y, x]
                    if kind == LINEAR:
                        res = march_linear(rays[y, x], depth, surface_ids, own, thickness,
                                           max_steps, p00, p11)
                    else:
                        res = march_dda(rays[y, x], depth, surface_ids, own, thickness, stride,
                                        jitter, max_steps)
                    _store_march(res, y, x, hit, hx, hy, dist, gap, lookups)
            y0, y1 = claim_rows(claimed, h)


@njit(cache=True, inline="always")
def _store_march(res, y, x, hit, hx, hy, dist, gap, lookups):
    """A march's (hit, hx, hy, distance, gap, lookups) into the output arrays at (y, x)."""
    hit[y, x] = res[0]
    hx[y, x] = res[1]
    hy[y, x] = res[2]
    dist[y, x] = res[3]
    gap[y, x] = res[4]
    lookups[y, x] = res[5]
