"""Surface shading shared by the rasterizer and the ray tracer (numba).

Both call `surface_color` on a hit, so that two techniques differ only in their reflections.
Inputs are world-space points, normals and view directions; uv in the material's UV space.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .scene.types import CHECKER, POINT, TEXTURE, UNLIT

# No fastmath: kernels here meet +inf depths (see STACK-NOTES.md).
# inline="always" (numba IR inlining): a plain call of these is not inlined by LLVM (too big
# with the light loop and the bilinear texture path) and costs more than the unlit checker
# shading itself: the ray tracer's shading of a 640x480 wave went from 10 to 4 ms (1 thread).


@njit(cache=True)
def _texel(texels, offset, w, h, x, y):
    x = x % w
    y = y % h
    k = offset + y * w + x
    return texels[k, 0], texels[k, 1], texels[k, 2]


@njit(cache=True, inline="always")
def material_albedo(mat, u, v, mat_i, mat_f, texels):
    """The material's linear RGB at (u, v). (Material and column indices unsigned: numba
    then leaves out each signed index's test for a negative value, Python's wraparound.)"""
    m = np.uint64(mat)
    kind = mat_i[m, 0]
    if kind == CHECKER:
        i = math.floor(u * mat_f[m, 6])
        j = math.floor(v * mat_f[m, 7])
        # the parity by its low bit (two's complement: also for negative sums), not % 2,
        # whose Python sign rule costs a branch
        c = np.uint64(0) if (int(i) + int(j)) & 1 == 0 else np.uint64(3)
        return mat_f[m, c], mat_f[m, c + np.uint64(1)], mat_f[m, c + np.uint64(2)]
    if kind == TEXTURE:
        off, w, h = mat_i[m, 1], mat_i[m, 2], mat_i[m, 3]
        su = u * mat_f[m, 6]
        sv = v * mat_f[m, 7]
        fx = (su - math.floor(su)) * w  # map space: texel units, row 0 at the top (v = 1)
        fy = (1.0 - (sv - math.floor(sv))) * h
        if mat_i[m, 4] == 0:
            return _texel(texels, off, w, h, int(fx), int(fy))
        fx -= 0.5
        fy -= 0.5
        x0 = math.floor(fx)
        y0 = math.floor(fy)
        ax = fx - x0
        ay = fy - y0
        x0i = int(x0)
        y0i = int(y0)
        r00, g00, b00 = _texel(texels, off, w, h, x0i, y0i)
        r10, g10, b10 = _texel(texels, off, w, h, x0i + 1, y0i)
        r01, g01, b01 = _texel(texels, off, w, h, x0i, y0i + 1)
        r11, g11, b11 = _texel(texels, off, w, h, x0i + 1, y0i + 1)
        w00 = (1 - ax) * (1 - ay)
        w10 = ax * (1 - ay)
        w01 = (1 - ax) * ay
        w11 = ax * ay
        return (
            w00 * r00 + w10 * r10 + w01 * r01 + w11 * r11,
            w00 * g00 + w10 * g10 + w01 * g01 + w11 * g11,
            w00 * b00 + w10 * b10 + w01 * b01 + w11 * b11,
        )
    return mat_f[m, 0], mat_f[m, 1], mat_f[m, 2]


@njit(cache=True, inline="always")
def surface_color(
    mat, u, v, px, py, pz, nx, ny, nz, dx, dy, dz, mat_i, mat_f, texels, light_f, shading, ambient
):
    """Color leaving a surface point toward the viewer; (dx, dy, dz) is the incoming ray.

    unlit: the albedo. lambert: ambient * albedo + sum over lights of albedo * E * max(0, n.l),
    two-sided (the normal is turned toward the viewer), no shadows.
    """
    ar, ag, ab = material_albedo(mat, u, v, mat_i, mat_f, texels)
    if shading == UNLIT:
        return ar, ag, ab
    inv_len = 1.0 / math.sqrt(nx * nx + ny * ny + nz * nz)
    nx, ny, nz = nx * inv_len, ny * inv_len, nz * inv_len
    if nx * dx + ny * dy + nz * dz > 0.0:
        nx, ny, nz = -nx, -ny, -nz
    er = eg = eb = ambient
    for k in range(light_f.shape[0]):
        if light_f[k, 0] == POINT:
            lx = light_f[k, 1] - px
            ly = light_f[k, 2] - py
            lz = light_f[k, 3] - pz
            nl = nx * lx + ny * ly + nz * lz
            if not nl > 0.0:  # facing away (cos <= 0): no light, and no square root
                continue
            inv = 1.0 / math.sqrt(lx * lx + ly * ly + lz * lz)
            scale = nl * inv * (inv * inv)  # cos / d^2
        else:
            scale = -(nx * light_f[k, 1] + ny * light_f[k, 2] + nz * light_f[k, 3])
            if not scale > 0.0:
                continue
        er += light_f[k, 4] * scale
        eg += light_f[k, 5] * scale
        eb += light_f[k, 6] * scale
    return ar * er, ag * eg, ab * eb
