"""Raster buffers -> colors: the shared shading of whatever the rasterizer left visible."""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

from ..parallel import claim, counter
from ..prefetch import prefetch
from ..scene.types import POINT, UNLIT, Scene, Triangles
from ..shading import material_albedo, surface_color
from .rasterize import RasterBuffers, clip_corners
from .rasterize.resolve import resolve_row


def shade_buffers(
    buffers: RasterBuffers, tris: Triangles, scene: Scene, eye: np.ndarray,
    incoming: np.ndarray | None = None, stencil: np.ndarray | None = None,
    out: tuple[np.ndarray, np.ndarray] | None = None,
    box: tuple[int, int, int, int] | None = None,
    pending: tuple | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(rgb (H, W, 3) float32, surface id (H, W) int32).

    Object pixels get their shaded color; mirror pixels get (1 - r) * base, the part of the
    mirror's color that does not depend on the reflection (techniques add r * reflected);
    background pixels get the scene background. `eye` is the world-space viewpoint: each
    point is shaded as seen along the ray eye -> point. `incoming` (H, W, 3, world), when
    given, is instead each pixel's own ray direction arriving at its point (e.g. the
    reflected ray of a curved mirror's pixel, whose viewpoint differs per pixel); shading
    uses it only for its side (two-sided normals), as the ray tracer uses its ray.
    With `stencil` (H, W) bool only its pixels are shaded: the others keep whatever `out`
    (rgb, surface arrays to write into, e.g. kept from the last frame) held. `box` (rows
    y0..y1-1, columns x0..x1-1, screen) must hold every stencil pixel: only it is visited
    (a small reflector's pass then scans its box, not the image).
    `pending` (with a stencil and a box; `rasterize_passes(resolve=False)`'s): the pass's
    per-thread buffers not yet merged; each row is merged (`_resolve`'s row, clear False)
    just before it is shaded, in the same parallel region: one region less, and the row
    still in cache.
    """
    h, w = buffers.triangle.shape
    if out is None:
        rgb = np.empty((h, w, 3), np.float32)
        surf = np.empty((h, w), np.int32)
    else:
        rgb, surf = out
    if incoming is None:
        dirs, per_pixel = np.zeros((1, 1, 3)), False
    else:
        dirs, per_pixel = np.ascontiguousarray(incoming, np.float64), True
        assert dirs.shape == (h, w, 3)
    # barycentrics recovered per shaded pixel from the triangles the rasterizer drew (which
    # may differ from the shaded ones: virtual triangles shaded as their originals)
    if buffers.recover:
        b1 = b2 = np.zeros((1, 1), np.float32)
        m = np.ascontiguousarray(buffers.clip_from_world, np.float64)
        drawn = buffers.corners
    else:
        b1, b2, m, drawn = buffers.b1, buffers.b2, np.eye(4), np.zeros((1, 3, 3), np.float32)
    args = (buffers.triangle, b1, b2, buffers.recover, m, drawn, tris.corners, tris.uvs,
            tris.normals,
            tris.material, tris.surface, scene.n_objects, np.asarray(eye, np.float64),
            dirs, per_pixel,
            scene.materials.mat_i, scene.materials.mat_f, scene.materials.texels,
            scene.lights.light_f, scene.shading, scene.ambient, scene.background,
            scene.mirrors.reflectance, scene.mirrors.base, rgb, surf)
    # each pixel is written once, from its row alone: which thread shades a row (claimed
    # in pieces of _ROWS, parallel.py) never changes the result
    threads = max(1, numba.get_num_threads())  # workers, each with its own scratch
    if pending is not None:
        assert stencil is not None and box is not None and buffers.recover
        assert tuple(box) == tuple(pending[3:5]) + tuple(pending[1:3])  # the pass's box
        _shade_stencil_resolving(np.ascontiguousarray(stencil, dtype=np.bool_), *args, *box,
                                 threads, *pending)
    elif stencil is None:
        _shade(*args, threads)
    else:
        y0, y1, x0, x1 = (0, h, 0, w) if box is None else box
        _shade_stencil(np.ascontiguousarray(stencil, dtype=np.bool_), *args, y0, y1, x0, x1,
                       threads)
    return rgb, surf


_ROWS = 4  # rows a thread claims at a time
_AHEAD = 8  # pixels between a triangle's prefetch and its use (_shade_row)


@njit(cache=True, parallel=True)
def _shade(tri, b1, b2, recover, m, drawn, corners, uvs, normals, material, surface,
           n_objects, eye, dirs, per_pixel, mat_i, mat_f, texels, light_f, shading, ambient,
           background, refl, base, rgb, surf, threads):
    """Every pixel shaded. `recover`: barycentrics from the clip-space corners of the
    triangles drawn (`drawn`, world; clip from world `m`) instead of b1, b2; `threads`:
    how many workers (each its own scratch).

    Rows are claimed _ROWS at a time by whichever thread is free (parallel.py): with a
    fixed share per thread, one thread could get the rows of every object while the other
    shaded background. (The row loop is written out in each kernel: called as a function
    instead of inlined it ran at half the speed.)"""
    h, w = tri.shape
    no_stencil = np.empty((1, 1), np.bool_)  # never read (np.zeros: a parallel loop)
    no_stencil[0, 0] = False
    g = np.empty((threads, 12, w))
    xs = np.empty((threads, w), np.int64)
    claimed = counter()
    pieces = (h + _ROWS - 1) // _ROWS
    for me in prange(threads):
        while True:
            k = claim(claimed)
            if k >= pieces:
                break
            for y in range(k * _ROWS, min(h, (k + 1) * _ROWS)):
                if recover:
                    _shade_row(y, 0, w, no_stencil, False, g[me], xs[me], tri, m, drawn,
                               corners, uvs, normals, material, surface, n_objects, eye, dirs,
                               per_pixel, mat_i, mat_f, texels, light_f, shading, ambient,
                               background, refl, base, rgb, surf)
                    continue
                for x in range(w):
                    _shade_pixel(y, x, tri, b1, b2, corners, uvs, normals, material, surface,
                                 n_objects, eye, dirs, per_pixel, mat_i, mat_f, texels, light_f,
                                 shading, ambient, background, refl, base, rgb, surf)


@njit(cache=True, parallel=True)
def _shade_stencil(stencil, tri, b1, b2, recover, m, drawn, corners, uvs, normals, material,
                   surface, n_objects, eye, dirs, per_pixel, mat_i, mat_f, texels, light_f,
                   shading, ambient, background, refl, base, rgb, surf, y0, y1, x0, x1,
                   threads):
    """_shade of the pixels where `stencil` is set, all inside rows y0..y1-1 and columns
    x0..x1-1 (only they are visited); the others are left as they are."""
    w = tri.shape[1]
    g = np.empty((threads, 12, w))
    xs = np.empty((threads, w), np.int64)
    claimed = counter()
    pieces = (max(y1 - y0, 0) + _ROWS - 1) // _ROWS
    for me in prange(threads):
        while True:
            k = claim(claimed)
            if k >= pieces:
                break
            for y in range(y0 + k * _ROWS, min(y1, y0 + (k + 1) * _ROWS)):
                if recover:
                    _shade_row(y, x0, x1, stencil, True, g[me], xs[me], tri, m, drawn,
                               corners, uvs, normals, material, surface, n_objects, eye, dirs,
                               per_pixel, mat_i, mat_f, texels, light_f, shading, ambient,
                               background, refl, base, rgb, surf)
                    continue
                for x in range(x0, x1):
                    if stencil[y, x]:
                        _shade_pixel(y, x, tri, b1, b2, corners, uvs, normals, material,
                                     surface, n_objects, eye, dirs, per_pixel, mat_i, mat_f,
                                     texels, light_f, shading, ambient, background, refl, base,
                                     rgb, surf)


@njit(cache=True, parallel=True)
def _shade_stencil_resolving(stencil, tri, b1, b2, recover, m, drawn, corners, uvs, normals,
                             material, surface, n_objects, eye, dirs, per_pixel, mat_i, mat_f,
                             texels, light_f, shading, ambient, background, refl, base, rgb,
                             surf, y0, y1, x0, x1, threads, flags, col0, col1, top, bottom,
                             own_tri, own_key, drew, depth):
    """_shade_stencil (barycentrics recovered) of a pass whose threads' buffers are merged
    here: rows y0..y1-1 (the pass's box [top, bottom) x [col0, col1)) are claimed _ROWS at
    a time, each merged into `tri` and `depth` (`_resolve`'s row, clear False: the same
    bytes) and then shaded. A row's shading reads only that row's ids."""
    w = tri.shape[1]
    owners = np.flatnonzero(drew)
    g = np.empty((threads, 12, w))
    xs = np.empty((threads, w), np.int64)
    claimed = counter()
    pieces = (max(y1 - y0, 0) + _ROWS - 1) // _ROWS
    for me in prange(threads):
        while True:
            k = claim(claimed)
            if k >= pieces:
                break
            for y in range(y0 + k * _ROWS, min(y1, y0 + (k + 1) * _ROWS)):
                resolve_row(flags, y, col0, col1, top, bottom, col0, col1, owners, own_tri,
                            own_key, tri, depth)
                _shade_row(y, x0, x1, stencil, True, g[me], xs[me], tri, m, drawn, corners,
                           uvs, normals, material, surface, n_objects, eye, dirs, per_pixel,
                           mat_i, mat_f, texels, light_f, shading, ambient, background, refl,
                           base, rgb, surf)


@njit(cache=True, inline="always")
def _run_weights(drawn, t, m, ny):
    """_run_setup's barycentric numerators along the row: (a0, a1, a2, e0, e1, e2)."""
    x0, x1, x2, y0, y1, y2, w0, w1, w2 = clip_corners(drawn, t, m)
    v0, v1, v2 = y0 - ny * w0, y1 - ny * w1, y2 - ny * w2
    a0, e0 = x1 * v2 - x2 * v1, w1 * v2 - w2 * v1
    a1, e1 = x2 * v0 - x0 * v2, w2 * v0 - w0 * v2
    a2, e2 = x0 * v1 - x1 * v0, w0 * v1 - w1 * v0
    return a0, a1, a2, e0, e1, e2


@njit(cache=True, inline="always")
def _run_setup_albedo(drawn, t, m, ny, uvs):
    """_run_setup as far as unlit shading reads it (the denominator, u and v; the rest 0):
    the same values, without reading the triangle's corners and normals (in a virtual pass
    each pixel is a triangle of its own, whose rows are memory waits)."""
    a0, a1, a2, e0, e1, e2 = _run_weights(drawn, t, m, ny)
    return (a0 + a1 + a2, e0 + e1 + e2,
            a0 * uvs[t, 0, 0] + a1 * uvs[t, 1, 0] + a2 * uvs[t, 2, 0],
            e0 * uvs[t, 0, 0] + e1 * uvs[t, 1, 0] + e2 * uvs[t, 2, 0],
            a0 * uvs[t, 0, 1] + a1 * uvs[t, 1, 1] + a2 * uvs[t, 2, 1],
            e0 * uvs[t, 0, 1] + e1 * uvs[t, 1, 1] + e2 * uvs[t, 2, 1],
            0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@njit(cache=True, inline="always")
def _run_setup(drawn, t, m, ny, corners, uvs, normals):
    """Triangle t's attributes along pixel row NDC y = ny, as affine functions of NDC x:
    u, v, p (world) and n each (numerator at nx = 0, its slope), and the denominator; the
    attribute at nx is (a - nx * e) / (D0 - nx * De).

    Barycentrics are b_i = d_i / (d0 + d1 + d2) with d_i the 2D cross products of the other
    two corners' (x - nx w, y - ny w) (`barycentrics_at`); along a row each d_i is
    a_i - nx * e_i, so each interpolated attribute sum_i A_i b_i is (sum A_i a_i - nx sum A_i
    e_i) / (sum a_i - nx sum e_i): the same perspective-correct interpolation, worked once per
    run of a triangle's pixels instead of per pixel."""
    a0, a1, a2, e0, e1, e2 = _run_weights(drawn, t, m, ny)
    return (a0 + a1 + a2, e0 + e1 + e2,
            a0 * uvs[t, 0, 0] + a1 * uvs[t, 1, 0] + a2 * uvs[t, 2, 0],
            e0 * uvs[t, 0, 0] + e1 * uvs[t, 1, 0] + e2 * uvs[t, 2, 0],
            a0 * uvs[t, 0, 1] + a1 * uvs[t, 1, 1] + a2 * uvs[t, 2, 1],
            e0 * uvs[t, 0, 1] + e1 * uvs[t, 1, 1] + e2 * uvs[t, 2, 1],
            a0 * corners[t, 0, 0] + a1 * corners[t, 1, 0] + a2 * corners[t, 2, 0],
            e0 * corners[t, 0, 0] + e1 * corners[t, 1, 0] + e2 * corners[t, 2, 0],
            a0 * corners[t, 0, 1] + a1 * corners[t, 1, 1] + a2 * corners[t, 2, 1],
            e0 * corners[t, 0, 1] + e1 * corners[t, 1, 1] + e2 * corners[t, 2, 1],
            a0 * corners[t, 0, 2] + a1 * corners[t, 1, 2] + a2 * corners[t, 2, 2],
            e0 * corners[t, 0, 2] + e1 * corners[t, 1, 2] + e2 * corners[t, 2, 2],
            a0 * normals[t, 0, 0] + a1 * normals[t, 1, 0] + a2 * normals[t, 2, 0],
            e0 * normals[t, 0, 0] + e1 * normals[t, 1, 0] + e2 * normals[t, 2, 0],
            a0 * normals[t, 0, 1] + a1 * normals[t, 1, 1] + a2 * normals[t, 2, 1],
            e0 * normals[t, 0, 1] + e1 * normals[t, 1, 1] + e2 * normals[t, 2, 1],
            a0 * normals[t, 0, 2] + a1 * normals[t, 1, 2] + a2 * normals[t, 2, 2],
            e0 * normals[t, 0, 2] + e1 * normals[t, 1, 2] + e2 * normals[t, 2, 2])


@njit(cache=True, inline="always")
def _shade_row(y, x0, x1, stencil, use_stencil, g, xs, tri, m, drawn, corners, uvs, normals,
               material, surface, n_objects, eye, dirs, per_pixel, mat_i, mat_f, texels,
               light_f, shading, ambient, background, refl, base, rgb, surf):
    """Columns x0..x1-1 of row y of a pass whose barycentrics are recovered (see
    _run_setup); with use_stencil only the pixels where `stencil` is set.

    Lit rows go in two steps: each object pixel's albedo, point, normal and view direction
    are gathered into columns of the scratch `g` (12, W), their columns in `xs` (W,), then
    `_light_row` lights the columns (loops without branches over contiguous arrays: the
    compiler vectorizes their square roots and divisions) in surface_color's order of
    operations: the same numbers."""
    h, w = tri.shape
    ny = 1.0 - (y + 0.5) * (2.0 / h)
    sx = 2.0 / w
    lit = shading != UNLIT
    count = 0
    last = -1  # the triangle whose run setup `co` holds (kept along the row)
    co = (0.0,) * 18
    ahead = -1  # the triangle last prefetched
    for x in range(x0, x1):
        # the triangle _AHEAD pixels on: its attributes asked for now (memory-bound passes
        # of tiny triangles, each pixel's its own, otherwise wait for one row at a time)
        t_ahead = tri[y, min(x + _AHEAD, x1 - 1)]
        if t_ahead != ahead:
            ahead = t_ahead
            if lit:
                prefetch(corners, t_ahead)
                prefetch(normals, t_ahead)
            prefetch(uvs, t_ahead)
            prefetch(drawn, t_ahead)
            prefetch(surface, t_ahead)
        if use_stencil and not stencil[y, x]:
            continue
        t = tri[y, x]
        if not _object_pixel(y, x, t, surface, n_objects, background, refl, base, rgb, surf):
            continue
        if t != last:
            last = t
            co = (_run_setup(drawn, t, m, ny, corners, uvs, normals) if lit
                  else _run_setup_albedo(drawn, t, m, ny, uvs))
        nx = (x + 0.5) * sx - 1.0
        q = 1.0 / (co[0] - nx * co[1])
        u = (co[2] - nx * co[3]) * q
        v = (co[4] - nx * co[5]) * q
        r, gr, bl = material_albedo(material[t], u, v, mat_i, mat_f, texels)
        if not lit:
            rgb[y, x, 0] = r
            rgb[y, x, 1] = gr
            rgb[y, x, 2] = bl
            continue
        px = (co[6] - nx * co[7]) * q
        py = (co[8] - nx * co[9]) * q
        pz = (co[10] - nx * co[11]) * q
        g[0, count], g[1, count], g[2, count] = r, gr, bl
        g[3, count], g[4, count], g[5, count] = px, py, pz
        g[6, count] = (co[12] - nx * co[13]) * q
        g[7, count] = (co[14] - nx * co[15]) * q
        g[8, count] = (co[16] - nx * co[17]) * q
        if per_pixel:
            g[9, count], g[10, count], g[11, count] = dirs[y, x, 0], dirs[y, x, 1], dirs[y, x, 2]
        else:
            g[9, count], g[10, count], g[11, count] = px - eye[0], py - eye[1], pz - eye[2]
        xs[count] = x
        count += 1
    if count:
        _light_row(g, count, light_f, ambient)
        for j in range(count):
            x = xs[j]
            rgb[y, x, 0] = g[0, j]
            rgb[y, x, 1] = g[1, j]
            rgb[y, x, 2] = g[2, j]


@njit(cache=True, inline="always")
def _light_row(g, count, light_f, ambient):
    """Lambert lighting of the first `count` columns of a row's gathered columns `g` (see
    _shade_row), written over its albedo rows: surface_color's lambert, column by column."""
    ar, ag, ab = g[0], g[1], g[2]
    px, py, pz = g[3], g[4], g[5]
    nx, ny, nz = g[6], g[7], g[8]
    er, eg, eb = g[9], g[10], g[11]  # the view direction, then the irradiance
    for j in range(count):
        inv_len = 1.0 / math.sqrt(nx[j] * nx[j] + ny[j] * ny[j] + nz[j] * nz[j])
        a, b, c = nx[j] * inv_len, ny[j] * inv_len, nz[j] * inv_len
        sign = -1.0 if a * er[j] + b * eg[j] + c * eb[j] > 0.0 else 1.0
        nx[j], ny[j], nz[j] = sign * a, sign * b, sign * c
        er[j] = ambient
        eg[j] = ambient
        eb[j] = ambient
    for k in range(light_f.shape[0]):
        ir, ig, ib = light_f[k, 4], light_f[k, 5], light_f[k, 6]
        if light_f[k, 0] == POINT:
            qx, qy, qz = light_f[k, 1], light_f[k, 2], light_f[k, 3]
            for j in range(count):
                lx = qx - px[j]
                ly = qy - py[j]
                lz = qz - pz[j]
                nl = nx[j] * lx + ny[j] * ly + nz[j] * lz
                inv = 1.0 / math.sqrt(lx * lx + ly * ly + lz * lz)
                scale = nl * inv * (inv * inv) if nl > 0.0 else 0.0
                er[j] += ir * scale
                eg[j] += ig * scale
                eb[j] += ib * scale
        else:
            qx, qy, qz = light_f[k, 1], light_f[k, 2], light_f[k, 3]
            for j in range(count):
                scale = -(nx[j] * qx + ny[j] * qy + nz[j] * qz)
                scale = scale if scale > 0.0 else 0.0
                er[j] += ir * scale
                eg[j] += ig * scale
                eb[j] += ib * scale
    for j in range(count):
        ar[j] *= er[j]
        ag[j] *= eg[j]
        ab[j] *= eb[j]


@njit(cache=True, inline="always")
def _object_pixel(y, x, t, surface, n_objects, background, refl, base, rgb, surf):
    """Writes the surface id; a background pixel (t < 0) and a mirror pixel (its unreflected
    part, (1 - reflectance) * base) get their colour here. True for an object's pixel, which
    the caller shades."""
    if t < 0:
        surf[y, x] = -1
        for c in range(3):
            rgb[y, x, c] = background[c]
        return False
    s = surface[t]
    surf[y, x] = s
    if s >= n_objects:
        k = s - n_objects
        for c in range(3):
            rgb[y, x, c] = (1.0 - refl[k, c]) * base[k, c]
        return False
    return True


@njit(cache=True, inline="always")
def _shade_pixel(y, x, tri, b1, b2, corners, uvs, normals, material, surface, n_objects, eye,
                 dirs, per_pixel, mat_i, mat_f, texels, light_f, shading, ambient, background,
                 refl, base, rgb, surf):
    """One pixel of a pass with stored barycentrics b1, b2."""
    t = tri[y, x]
    if not _object_pixel(y, x, t, surface, n_objects, background, refl, base, rgb, surf):
        return
    c1 = b1[y, x]
    c2 = b2[y, x]
    c0 = 1.0 - c1 - c2
    u = c0 * uvs[t, 0, 0] + c1 * uvs[t, 1, 0] + c2 * uvs[t, 2, 0]
    v = c0 * uvs[t, 0, 1] + c1 * uvs[t, 1, 1] + c2 * uvs[t, 2, 1]
    px = c0 * corners[t, 0, 0] + c1 * corners[t, 1, 0] + c2 * corners[t, 2, 0]
    py = c0 * corners[t, 0, 1] + c1 * corners[t, 1, 1] + c2 * corners[t, 2, 1]
    pz = c0 * corners[t, 0, 2] + c1 * corners[t, 1, 2] + c2 * corners[t, 2, 2]
    nx = c0 * normals[t, 0, 0] + c1 * normals[t, 1, 0] + c2 * normals[t, 2, 0]
    ny = c0 * normals[t, 0, 1] + c1 * normals[t, 1, 1] + c2 * normals[t, 2, 1]
    nz = c0 * normals[t, 0, 2] + c1 * normals[t, 1, 2] + c2 * normals[t, 2, 2]
    if per_pixel:
        dx, dy, dz = dirs[y, x, 0], dirs[y, x, 1], dirs[y, x, 2]
    else:
        dx, dy, dz = px - eye[0], py - eye[1], pz - eye[2]
    r, g, bl = surface_color(material[t], u, v, px, py, pz, nx, ny, nz, dx, dy, dz,
                             mat_i, mat_f, texels, light_f, shading, ambient)
    rgb[y, x, 0] = r
    rgb[y, x, 1] = g
    rgb[y, x, 2] = bl


@njit(cache=True)
def add_reflection(rgb, reflected, stencil, reflectance, y0, y1, x0, x1):
    """rgb += reflectance * reflected on the pixels of `stencil` inside rows y0..y1-1 and
    columns x0..x1-1 (its box): a mirror's reflection added to its (1 - r) * base."""
    for y in range(y0, y1):
        for x in range(x0, x1):
            if stencil[y, x]:
                for c in range(3):
                    rgb[y, x, c] += reflectance[c] * reflected[y, x, c]
