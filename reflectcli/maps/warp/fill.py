"""dprm's fill: each mirror pixel's warped colour, else the previous frame's, else the
background, blended into the frame."""

from __future__ import annotations

from numba import njit, prange


@njit(cache=True, parallel=True)
def fill_blend(stencil, best_id, reflected, has_prev, prev_rgb, prev_filled, temporal,
                save_rgb, save_filled, background, reflectance, rgb, holes):
    """Per mirror pixel: the warped color, else (temporal) the previous frame's, else the
    background (a hole); rgb += reflectance * that. With `temporal`, save_rgb/save_filled
    receive this frame's reflected colors and filled pixels for the next frame."""
    h, w = stencil.shape
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
