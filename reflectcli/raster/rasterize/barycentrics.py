"""Barycentrics recovered from the visible triangle's clip-space corners and the pixel
center's NDC: perspective-correct by construction, the same for clipped triangles, so the
rasterizer never writes them per fragment."""

from numba import njit, prange


@njit(cache=True, inline="always")
def clip_corners(corners, t, m):
    """Clip-space x, y and w of triangle t's corners (world `corners`, clip from world `m`):
    (x0, x1, x2, y0, y1, y2, w0, w1, w2), what barycentrics_at needs."""
    x0, y0, z0 = corners[t, 0, 0], corners[t, 0, 1], corners[t, 0, 2]  # float32 -> float64
    x1, y1, z1 = corners[t, 1, 0], corners[t, 1, 1], corners[t, 1, 2]
    x2, y2, z2 = corners[t, 2, 0], corners[t, 2, 1], corners[t, 2, 2]
    out = (m[0, 0] * x0 + m[0, 1] * y0 + m[0, 2] * z0 + m[0, 3],
           m[0, 0] * x1 + m[0, 1] * y1 + m[0, 2] * z1 + m[0, 3],
           m[0, 0] * x2 + m[0, 1] * y2 + m[0, 2] * z2 + m[0, 3],
           m[1, 0] * x0 + m[1, 1] * y0 + m[1, 2] * z0 + m[1, 3],
           m[1, 0] * x1 + m[1, 1] * y1 + m[1, 2] * z1 + m[1, 3],
           m[1, 0] * x2 + m[1, 1] * y2 + m[1, 2] * z2 + m[1, 3],
           m[3, 0] * x0 + m[3, 1] * y0 + m[3, 2] * z0 + m[3, 3],
           m[3, 0] * x1 + m[3, 1] * y1 + m[3, 2] * z1 + m[3, 3],
           m[3, 0] * x2 + m[3, 1] * y2 + m[3, 2] * z2 + m[3, 3])
    return out


@njit(cache=True, inline="always")
def barycentrics_at(c, nx, ny):
    """(b1, b2): weights of corners 1 and 2 at the point of the triangle's plane seen through
    NDC (nx, ny), from its clip_corners `c`: the weights are proportional to the 2D cross
    products of the other two corners' (x - nx w, y - ny w). Perspective-correct, and right
    for triangles the rasterizer clipped."""
    u0, u1, u2 = c[0] - nx * c[6], c[1] - nx * c[7], c[2] - nx * c[8]
    v0, v1, v2 = c[3] - ny * c[6], c[4] - ny * c[7], c[5] - ny * c[8]
    d0 = u1 * v2 - u2 * v1
    d1 = u2 * v0 - u0 * v2
    d2 = u0 * v1 - u1 * v0
    inv = 1.0 / (d0 + d1 + d2)
    return d1 * inv, d2 * inv


@njit(cache=True, inline="always")
def recover_barycentrics(corners, t, m, nx, ny):
    """(b1, b2) of triangle t at NDC (nx, ny): barycentrics_at of its clip_corners."""
    return barycentrics_at(clip_corners(corners, t, m), nx, ny)


@njit(cache=True, parallel=True, error_model="numpy")
def _barycentrics(tri, corners, m, b1, b2):
    """b1, b2 of every pixel's triangle (0 where none), by recover_barycentrics."""
    h, w = tri.shape
    for py in prange(h):
        ny = 1.0 - (py + 0.5) * (2.0 / h)
        for px in range(w):
            t = tri[py, px]
            if t < 0:
                b1[py, px] = 0.0
                b2[py, px] = 0.0
                continue
            c1, c2 = recover_barycentrics(corners, t, m, (px + 0.5) * (2.0 / w) - 1.0, ny)
            b1[py, px] = c1
            b2[py, px] = c2
