"""dprm's fill: each mirror pixel's warped colour, else the previous frame's, else the
background, blended into the frame."""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, parallel=True)
def fill_blend(stencil, best_id, reflected, has_prev, prev_rgb, prev_filled, temporal,
                save_rgb, save_filled, background, reflectance, rgb, holes):
    """Per mirror pixel: the warped color, else (temporal) the previous frame's, else the
    background (a hole); rgb += reflectance * that. With `temporal`, save_rgb/save_filled
    receive this frame's reflected colors and filled pixels for the next frame."""
    h, w = stencil.shape
    if not has_prev and not temporal:  # the common case: rows without branches
        for y in prange(h):
            _fill_row(stencil[y], best_id[y], reflected[y], background, reflectance, rgb[y],
                      holes[y])
        return
    for y in prange(h):
        for x in range(w):
            if not stencil[y, x]:
                if temporal:
                    save_filled[y, x] = False
                continue
            filled = best_id[y, x] >= 0
            if not filled and has_prev and prev_filled[y, x]:
                for c in range(3):
                    reflected[y, x, c] = prev_rgb[y, x, c]
                filled = True
            if temporal:
                save_filled[y, x] = filled
                if filled:
                    for c in range(3):
                        save_rgb[y, x, c] = reflected[y, x, c]
            if not filled:
                for c in range(3):
                    reflected[y, x, c] = background[c]
                holes[y, x] = 1.0
            for c in range(3):
                rgb[y, x, c] += reflectance[c] * reflected[y, x, c]


@njit(cache=True, inline="always")
def _fill_row(on, ids, reflected, background, reflectance, rgb, holes):
    """One row of `fill_blend` without a previous frame (reflected, rgb: the row's (W, 3)),
    written with selects (no branches); a pixel off the stencil, or a value the rule leaves
    alone, is written back as it was read (the same bytes)."""
    b0, b1, b2 = background[0], background[1], background[2]
    f0, f1, f2 = reflectance[0], reflectance[1], reflectance[2]
    one = np.float32(1.0)
    for x in range(on.shape[0]):
        s = on[x]
        filled = ids[x] >= 0
        c0 = reflected[x, 0]
        c1 = reflected[x, 1]
        c2 = reflected[x, 2]
        r0 = c0 if filled else b0
        r1 = c1 if filled else b1
        r2 = c2 if filled else b2
        reflected[x, 0] = r0 if s else c0
        reflected[x, 1] = r1 if s else c1
        reflected[x, 2] = r2 if s else c2
        o0 = rgb[x, 0]
        o1 = rgb[x, 1]
        o2 = rgb[x, 2]
        rgb[x, 0] = o0 + f0 * r0 if s else o0
        rgb[x, 1] = o1 + f1 * r1 if s else o1
        rgb[x, 2] = o2 + f2 * r2 if s else o2
        holes[x] = one if s and not filled else holes[x]
