"""Slow, obviously correct twins of the fast kernels (after STUMPY's tests/naive.py).

One function (or a small group) per numba kernel in reflectcli, written for clarity: plain
Python loops or whole-array numpy, float64, no bands, no bounding boxes, no hoisted terms,
and where there is an independent way to the answer (scipy's interpolation, a root finder,
a brute-force search, the Camera's own matrices) it is used. Each docstring names the kernel
it twins; tests/test_twins.py checks that every @njit kernel is held to one.

Sections: shading, camera, raster, trace, maps (cube / sphere / lookup / surface / warp),
virtual (direct / refine / explosion).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import map_coordinates
from scipy.optimize import brentq, minimize_scalar

from reflectcli.maps.distance_search import CREASE_SLOPE
from reflectcli.raster.rasterize import FLAG_CULL_BACK, FLAG_CULL_FRONT, FLAG_MIRROR, FLAG_SKIP
from reflectcli.scene.types import (
    CHECKER,
    CYLINDER,
    MIRROR_TIE,
    PLANAR,
    POINT,
    SPHERE,
    TEXTURE,
    UNLIT,
)

# ================================================================================= shading


def _bary(b1, b2):
    """Barycentric weights (b0, b1, b2) in float64 (b0 = 1 - b1 - b2, worked in float64)."""
    b1, b2 = float(b1), float(b2)
    return np.array([1.0 - b1 - b2, b1, b2])


def material_albedo(mat, u, v, mat_i, mat_f, texels):
    """Twin of shading.material_albedo (and shading._texel): the material's RGB at (u, v).

    solid: color0; checker: color0 where floor(u su) + floor(v sv) is even, else color1;
    texture: the image tiled over uv space (uv scaled, row 0 at v = 1), nearest texel or a
    bilinear blend of texel centers with wrap-around (scipy's grid-wrap interpolation)."""
    kind = int(mat_i[mat, 0])
    f = np.asarray(mat_f[mat], np.float64)
    if kind == CHECKER:
        parity = (math.floor(u * f[6]) + math.floor(v * f[7])) % 2
        return tuple(f[0:3] if parity == 0 else f[3:6])
    if kind == TEXTURE:
        off, w, h, bilinear = (int(x) for x in mat_i[mat, 1:5])
        image = np.asarray(texels[off:off + w * h], np.float64).reshape(h, w, 3)
        su, sv = u * f[6], v * f[7]
        x = (su - math.floor(su)) * w  # texel units, x right
        y = (1.0 - (sv - math.floor(sv))) * h  # texel units, y down from the top row
        if not bilinear:
            return tuple(image[int(y) % h, int(x) % w])
        # texel (i, j) has its center at (i + 0.5, j + 0.5): sample at (y - 0.5, x - 0.5)
        return tuple(float(map_coordinates(image[:, :, c], [[y - 0.5], [x - 0.5]], order=1,
                                           mode="grid-wrap")[0]) for c in range(3))
    return tuple(f[0:3])


def surface_color(mat, u, v, p, n, d, mat_i, mat_f, texels, light_f, shading, ambient):
    """Twin of shading.surface_color: vectors p (point), n (normal), d (incoming ray).

    unlit: the albedo; lambert: albedo * (ambient + sum of E * max(0, cos) / r^2 for point
    lights, E * max(0, cos) for directional ones), the normal turned to face the viewer."""
    albedo = np.array(material_albedo(mat, u, v, mat_i, mat_f, texels))
    if shading == UNLIT:
        return albedo
    n = np.asarray(n, np.float64) / np.linalg.norm(n)
    if n @ np.asarray(d, np.float64) > 0:
        n = -n
    e = np.full(3, float(ambient))
    for light in np.asarray(light_f, np.float64):
        if int(light[0]) == POINT:
            to_light = light[1:4] - np.asarray(p, np.float64)
            r = np.linalg.norm(to_light)
            e += light[4:7] * max(n @ to_light / r, 0.0) / r**2
        else:  # directional: light[1:4] is the way the light travels
            e += light[4:7] * max(-(n @ light[1:4]), 0.0)
    return albedo * e


# ================================================================================== camera


def primary_rays(camera, samples):
    """Twin of trace.rays._primary_rays (and rows_of_rays): the camera's own numpy pixel
    directions (Camera.pixel_directions, row-major, s x s samples per pixel), rays from the
    near plane."""
    d = camera.pixel_directions(samples).reshape(-1, 3)
    return np.asarray(camera.eye, np.float64) + camera.near * d, d


# ================================================================================ parallel


def claim(counter):
    """Twin of parallel.claim on one thread: counter[0], then one more. The fast one is held
    to it by the frames' byte-identity across thread counts (rasterizer, ray tracer)."""
    k = int(counter[0])
    counter[0] = k + 1
    return k


def claim_rows(counter, h, rows_per_claim):
    """Twin of parallel.claim_rows on one thread: the band [k * rows, (k + 1) * rows) of the
    k-th claim, cut at h; empty once past it."""
    k = claim(counter)
    return min(k * rows_per_claim, h), min((k + 1) * rows_per_claim, h)


def prefetch(ary, index):
    """Twin of prefetch.prefetch: nothing, a hint to the memory system changes no value (the
    fast one is held to that by a gather with and without it, and by the shading passes)."""
    del ary, index


def prefetch_write(ary, index):
    """Twin of prefetch.prefetch_write: nothing, as `prefetch` (held to that by the same
    gather, and by the one-pixel splat, which asks for its payload rows with it)."""
    del ary, index


# ================================================================================== raster

EDGE_PX = 1e-6
TIE_REL = 1e-6


def rasterize(corners, flags, m, w, h, mask=None, depth_floor=None, cull=0):
    """Twin of raster.rasterize (its kernels draw._draw, setup._run_setup and its
    setup.triangle_cull, rows._fill, resolve._resolve and its rows resolve.resolve_row, the
    viewport of raster.rasterize.clip.screen_from_ndc, and the barycentrics of
    raster.rasterize.barycentrics.recover_barycentrics, clip_corners and barycentrics_at):
    a slow float64 z-buffer of triangles wholly inside near..far.

    Every pixel center against every triangle: clip-space transform, screen positions,
    inside test by screen-space edge functions (edges inclusive), perspective-correct
    barycentrics and depth through 1/w, nearest wins with a strict less-than in triangle
    order, mirrors (FLAG_MIRROR) with their depth scaled by MIRROR_TIE, FLAG_SKIP triangles
    left out. `mask` (H, W): only its pixels are drawn; `depth_floor` (H, W): fragments at or
    in front of it are dropped; `cull` 1 drops clockwise-on-screen (back) triangles, 2
    counter-clockwise; a triangle flagged FLAG_CULL_BACK is dropped when clockwise too,
    one flagged FLAG_CULL_FRONT when counter-clockwise.
    Returns (triangle, b1, b2, depth, ambiguous) with ambiguous marking
    pixels where either answer is fine (a center within EDGE_PX of a covering edge, two
    depths within TIE_REL, a depth within TIE_REL of the floor)."""
    c = corners.astype(np.float64)
    clip = np.concatenate([c, np.ones(c.shape[:2] + (1,))], axis=2) @ m.T  # (T, 3, 4)
    assert np.all(np.abs(clip[..., 2]) <= clip[..., 3]), "reference needs unclipped triangles"
    sx = (clip[..., 0] / clip[..., 3] + 1) * 0.5 * w
    sy = (1 - clip[..., 1] / clip[..., 3]) * 0.5 * h
    inv_w = 1.0 / clip[..., 3]
    py, px = np.mgrid[0:h, 0:w]
    cx, cy = (px + 0.5).reshape(-1, 1), (py + 0.5).reshape(-1, 1)  # (P, 1)

    def edge(a, b):  # signed doubled area of (corner a, corner b, pixel center), (P, T)
        return (sx[:, b] - sx[:, a]) * (cy - sy[:, a]) - (sy[:, b] - sy[:, a]) * (cx - sx[:, a])

    area = (sx[:, 1] - sx[:, 0]) * (sy[:, 2] - sy[:, 0]) - (
        sx[:, 2] - sx[:, 0]) * (sy[:, 1] - sy[:, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.stack([edge(1, 2), edge(2, 0), edge(0, 1)], axis=2) / area[None, :, None]
        lengths = np.stack([np.hypot(sx[:, 2] - sx[:, 1], sy[:, 2] - sy[:, 1]),
                            np.hypot(sx[:, 0] - sx[:, 2], sy[:, 0] - sy[:, 2]),
                            np.hypot(sx[:, 1] - sx[:, 0], sy[:, 1] - sy[:, 0])], axis=1)
        # distance in pixels from the center to each edge's line
        dist = lam * np.abs(area)[None, :, None] / lengths[None]
    drawn = (area != 0) & ((flags & FLAG_SKIP) == 0)
    if cull == 1:
        drawn &= ~(area > 0)
    elif cull == 2:
        drawn &= ~(area < 0)
    drawn &= ~(((flags & FLAG_CULL_BACK) != 0) & (area > 0))
    drawn &= ~(((flags & FLAG_CULL_FRONT) != 0) & (area < 0))
    valid = drawn[None, :]
    if mask is not None:
        valid = valid & np.asarray(mask, bool).reshape(-1, 1)
    inside = valid & np.all(lam >= 0, axis=2)
    near_edge = valid & np.all(lam >= -1e-3, axis=2) & np.any(np.abs(dist) <= EDGE_PX, axis=2)
    q = lam * inv_w[None]  # (P, T, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = 1.0 / q.sum(axis=2)
    floor = None
    if depth_floor is not None:
        floor = np.asarray(depth_floor, np.float64).reshape(-1, 1)
        with np.errstate(invalid="ignore"):
            at_floor = (inside | near_edge) & (np.abs(depth - floor) <= TIE_REL * floor)
            inside &= depth > floor
            near_edge &= depth > floor
    is_mirror = (flags & FLAG_MIRROR) != 0
    key = np.where(is_mirror[None], depth * MIRROR_TIE, depth)
    key = np.where(inside, key, np.inf)
    best = np.full(cx.shape[0], np.inf)
    tri = np.full(cx.shape[0], -1)
    for t in range(corners.shape[0]):  # triangle order, strict less-than
        win = key[:, t] < best
        best[win] = key[win, t]
        tri[win] = t
    p = np.arange(cx.shape[0])
    tt = np.maximum(tri, 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        b = q[p, tt] / q[p, tt].sum(axis=1, keepdims=True)
    b = np.where((tri >= 0)[:, None], b, 0.0)
    # ties: another covering (or nearly covering) triangle within TIE_REL of the winner
    cover = inside | near_edge
    kk = np.where(cover, np.where(is_mirror[None], depth * MIRROR_TIE, depth), np.inf)
    others = np.where(np.arange(corners.shape[0])[None] == tri[:, None], np.inf, kk)
    with np.errstate(invalid="ignore"):
        tie = np.isfinite(best) & (np.abs(others.min(axis=1) - best) <= TIE_REL * best)
    ambiguous = near_edge.any(axis=1) | tie
    if floor is not None:
        ambiguous |= at_floor.any(axis=1)
    depth_out = np.where(tri >= 0, np.where(is_mirror[tt], best / MIRROR_TIE, best), np.inf)
    shape = (h, w)
    return (tri.reshape(shape), b[:, 1].reshape(shape), b[:, 2].reshape(shape),
            depth_out.reshape(shape), ambiguous.reshape(shape))


# the name the rasterizer tests have always used
reference = rasterize


def ray_triangle(o: np.ndarray, d: np.ndarray, c: np.ndarray):
    """float64 Moller-Trumbore of rays (P, 3) against one triangle: t, u, v (the ray casting
    twin of the rasterizer's near-plane clipping, raster.rasterize.clip._clip_polygon)."""
    e1, e2 = c[1] - c[0], c[2] - c[0]
    p = np.cross(d, e2)
    det = p @ e1
    s = o - c[0]
    u = np.einsum("pk,pk->p", s, p) / det
    q = np.cross(s, e1)
    v = np.einsum("pk,pk->p", d, q) / det
    t = q @ e2 / det
    return t, u, v


def shade(tri, b1, b2, corners, uvs, normals, material, surface, n_objects, eye, mat_i, mat_f,
          texels, light_f, shading, ambient, background, refl, base, incoming=None):
    """Twin of raster.shade._shade: per pixel, background where nothing was drawn, the
    mirror's (1 - r) * base on mirrors, else the surface color at the barycentric blend of the
    triangle's corners, uvs and normals, seen from `eye` (or along the pixel's own ray
    `incoming[y, x]` when given). Returns (rgb, surface id)."""
    h, w = tri.shape
    rgb = np.zeros((h, w, 3))
    surf = np.full((h, w), -1)
    for y in range(h):
        for x in range(w):
            t = tri[y, x]
            if t < 0:
                rgb[y, x] = background
                continue
            s = surface[t]
            surf[y, x] = s
            if s >= n_objects:
                k = s - n_objects
                rgb[y, x] = (1.0 - refl[k].astype(np.float64)) * base[k]
                continue
            bary = _bary(b1[y, x], b2[y, x])
            uv = bary @ uvs[t].astype(np.float64)
            p = bary @ corners[t].astype(np.float64)
            n = bary @ normals[t].astype(np.float64)
            view = p - eye if incoming is None else incoming[y, x]
            rgb[y, x] = surface_color(material[t], uv[0], uv[1], p, n, view, mat_i, mat_f,
                                      texels, light_f, shading, ambient)
    return rgb, surf


def fill_fixed(t, key_scale, cull, x0, y0, w0, x1, y1, w1, x2, y2, w2, bits, top, bottom,
               col0, col1, stencil, use_stencil, floor, use_floor, tri, key):
    """Twin of raster.rasterize.rows._fill: every pixel of the box [top, bottom) x [col0, col1)
    (not the triangle's bounding box), Python integers for the edge functions (exact, no
    stepping), the top-left rule written as "a center on an edge belongs to the triangle
    on the side its inward normal points to: right, or down for a horizontal edge", and
    1/w from barycentric weights (not a plane). `tri`/`key` hold the box."""
    x0, y0, x1, y1, x2, y2 = (int(v) for v in (x0, y0, x1, y1, x2, y2))
    area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    if area == 0 or (cull == 1 and area > 0) or (cull == 2 and area < 0):
        return
    corners = [(x0, y0, w0), (x1, y1, w1), (x2, y2, w2)]
    if area < 0:
        corners = [corners[0], corners[2], corners[1]]
        area = -area
    edges = []
    for k in range(3):
        (xa, ya, _), (xb, yb, _) = corners[(k + 1) % 3], corners[(k + 2) % 3]
        nx, ny = ya - yb, xb - xa  # inward normal (screen y down, counter-clockwise here)
        edges.append((xa, ya, nx, ny, nx > 0 or (nx == 0 and ny > 0)))
    one = 1 << bits
    for py in range(top, bottom):
        for px in range(col0, col1):
            cx, cy = px * one + one // 2, py * one + one // 2
            e = [nx * (cx - xa) + ny * (cy - ya) for xa, ya, nx, ny, _ in edges]
            if not all(v > 0 or (v == 0 and owns) for v, (*_, owns) in zip(e, edges,
                                                                            strict=True)):
                continue
            inv_w = sum(v * c[2] for v, c in zip(e, corners, strict=True)) / area
            z = np.float32(inv_w * key_scale)
            if use_stencil and not stencil[py, px]:
                continue
            if use_floor and not 1.0 / inv_w > floor[py, px]:
                continue
            r, c = py - top, px - col0
            if z > key[r, c] or (z == key[r, c] and t < tri[r, c]):
                key[r, c] = z
                tri[r, c] = t


def stencil_box(stencil):
    """Twin of raster.rasterize.stencil.stencil_box: (x0, x1, y0, y1), the columns and rows
    holding every set pixel, by numpy's any along each axis; (0, 0, 0, 0) when none is set."""
    ys = np.flatnonzero(np.asarray(stencil).any(axis=1))
    xs = np.flatnonzero(np.asarray(stencil).any(axis=0))
    if ys.size == 0:
        return 0, 0, 0, 0
    return int(xs[0]), int(xs[-1]) + 1, int(ys[0]), int(ys[-1]) + 1


def run_bounds(corners, run):
    """Twin of raster.bounds.run_bounds: (runs, 6) min xyz, max xyz of each run of `run`
    triangles (T, 3, 3), by numpy (NaN where a run holds a NaN)."""
    out = []
    for t0 in range(0, len(corners), run):
        pts = corners[t0:t0 + run].reshape(-1, 3)
        out.append(np.concatenate([pts.min(axis=0), pts.max(axis=0)]))
    return np.array(out, np.float64).reshape(-1, 6)


def add_reflection(rgb, reflected, stencil, reflectance):
    """Twin of raster.shade.add_reflection (over the whole image: the box is an
    optimisation): rgb + reflectance * reflected where the stencil is set, in float32."""
    out = rgb.copy()
    part = (reflectance.astype(np.float32) * reflected).astype(np.float32)
    out[stencil] = (rgb[stencil] + part[stencil]).astype(np.float32)
    return out


def shade_stencil(stencil, rgb, surf, *args):
    """Twin of raster.shade._shade_stencil: `shade` where `stencil` is set, the given rgb and
    surface arrays untouched elsewhere. Returns (rgb, surface id) as new arrays."""
    want_rgb, want_surf = shade(*args)
    rgb = np.array(rgb, np.float64)
    surf = np.array(surf)
    rgb[stencil] = want_rgb[stencil]
    surf[stencil] = want_surf[stencil]
    return rgb, surf


# =================================================================================== trace

GRAZE = 1e-5  # barycentric margin: a ray this close to an edge may fall either side
T_REL = 1e-4


def moller_trumbore(corners: np.ndarray, o: np.ndarray, d: np.ndarray):
    """All ray-triangle pairs in float64: t, u, v (weights of corners 1, 2), det (R, T)."""
    c = corners.astype(np.float64)
    o, d = o.astype(np.float64), d.astype(np.float64)
    e1, e2 = c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]
    p = np.cross(d[:, None, :], e2[None])  # (R, T, 3)
    det = np.einsum("rtk,tk->rt", p, e1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = o[:, None, :] - c[None, :, 0]
        u = np.einsum("rtk,rtk->rt", s, p) * inv
        q = np.cross(s, e1[None])
        v = np.einsum("rk,rtk->rt", d, q) * inv
        t = np.einsum("tk,rtk->rt", e2, q) * inv
    return t, u, v, det


def brute_force(corners, o, d, tfar):
    """Twin of trace.embree.TriangleScene.intersect (Embree's packets: intersect_range in a
    packet_buffer; not numba): the nearest hit per ray over every triangle, and whether the
    ray is too close to call (grazing or a tie)."""
    with np.errstate(invalid="ignore", divide="ignore"):  # inf - inf on misses
        return _brute_force(corners, o, d, tfar)


def _brute_force(corners, o, d, tfar):
    t, u, v, det = moller_trumbore(corners, o, d)
    w = 1.0 - u - v
    ok = (det != 0) & np.isfinite(t)
    inside = ok & (u >= 0) & (v >= 0) & (w >= 0) & (t > 0) & (t <= tfar[:, None])
    margin = np.minimum(np.minimum(u, v), w)
    # within GRAZE of an edge of a triangle whose plane is met in range: either answer is fine
    graze = ok & (np.abs(margin) <= GRAZE) & (t > -1e-4) & (t <= tfar[:, None] * (1 + T_REL))
    # a ray nearly in a triangle's plane, or a hit at t ~ 0 or ~ tfar, is also ambiguous
    area2 = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                    corners[:, 2] - corners[:, 0]), axis=1)
    cosine = np.abs(det) / (area2[None] * np.linalg.norm(d, axis=1)[:, None])
    near_hit = ok & (margin >= -GRAZE)
    graze |= cosine < 1e-4  # a ray (nearly) along a triangle's plane
    graze |= near_hit & (np.abs(t) < 1e-4)
    finite = np.isfinite(tfar)[:, None]
    graze |= near_hit & finite & (np.abs(t - tfar[:, None]) <= T_REL * tfar[:, None])
    tt = np.where(inside, t, np.inf)
    prim = np.where(np.isfinite(tt.min(axis=1)), tt.argmin(axis=1), -1)
    best = tt.min(axis=1)
    second = np.sort(tt, axis=1)[:, 1] if tt.shape[1] > 1 else np.full(len(o), np.inf)
    tie = np.isfinite(second) & (second - best <= T_REL * np.abs(second))
    r = np.arange(len(o))
    return best, prim, u[r, np.maximum(prim, 0)], v[r, np.maximum(prim, 0)], graze.any(axis=1) | tie


def sphere_closed_form(o, d, c, r, tmin):
    """Twin of trace.analytic._sphere: roots of |o + t d - c|^2 = r^2 by the textbook
    formula (Newton-polished), and the discriminant."""
    oc = o - c
    a = np.einsum("rk,rk->r", d, d)
    b = 2 * np.einsum("rk,rk->r", oc, d)
    cc = np.einsum("rk,rk->r", oc, oc) - r * r
    disc = b * b - 4 * a * cc
    with np.errstate(invalid="ignore"):
        sq = np.sqrt(disc)
        t0, t1 = (-b - sq) / (2 * a), (-b + sq) / (2 * a)
        # the textbook roots lose digits to cancellation: polish each with Newton steps
        for _ in range(3):
            t0 = t0 - (a * t0 * t0 + b * t0 + cc) / (2 * a * t0 + b)
            t1 = t1 - (a * t1 * t1 + b * t1 + cc) / (2 * a * t1 + b)
    t = np.where(t0 > tmin, t0, np.where(t1 > tmin, t1, np.inf))
    t = np.where(disc >= 0, t, np.inf)
    return t, disc / (4 * a * a), np.stack([t0, t1], 1)


def cylinder_closed_form(o, d, origin, axis, r, h, tmin):
    """Twin of trace.analytic._cylinder: transform to a frame with the axis as local y and
    solve x^2 + z^2 = r^2, 0 <= y <= h. Returns (t, marginal)."""
    a = axis / np.linalg.norm(axis)
    helper = np.array([0.0, 0.0, 1.0]) if abs(a[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    ex = np.cross(helper, a)
    ex /= np.linalg.norm(ex)
    ez = np.cross(ex, a)
    basis = np.stack([ex, a, ez])
    lo, ld = (o - origin) @ basis.T, d @ basis.T
    qa = ld[:, 0] ** 2 + ld[:, 2] ** 2
    qb = 2 * (lo[:, 0] * ld[:, 0] + lo[:, 2] * ld[:, 2])
    qc = lo[:, 0] ** 2 + lo[:, 2] ** 2 - r * r
    disc = qb * qb - 4 * qa * qc
    with np.errstate(invalid="ignore", divide="ignore"):
        sq = np.sqrt(disc)
        roots = np.stack([(-qb - sq) / (2 * qa), (-qb + sq) / (2 * qa)], 1)
        for _ in range(3):  # Newton polish, as for the sphere
            roots = roots - (qa[:, None] * roots**2 + qb[:, None] * roots + qc[:, None]) / (
                2 * qa[:, None] * roots + qb[:, None])
    y = lo[:, 1:2] + roots * ld[:, 1:2]
    valid = (disc[:, None] >= 0) & (qa[:, None] > 0) & (roots > tmin) & (y >= 0) & (y <= h)
    t = np.where(valid, roots, np.inf).min(axis=1)
    # rims and tangent rays are ambiguous
    rim = (np.abs(y) < 1e-5 * (1 + h)) | (np.abs(y - h) < 1e-5 * (1 + h))
    marginal = (np.isfinite(roots) & rim).any(axis=1)
    marginal |= (disc >= 0) & (disc < 1e-8 * np.maximum(qb * qb, 1e-30))
    marginal |= (np.abs(roots - tmin) < 1e-6).any(axis=1)
    return t, marginal


def quad_closed_form(o, d, n, c00, e1, e2, tmin):
    """Twin of trace.analytic._quad (and _inner, quad_edges): ray-plane t, then the hit's
    coordinates along the rectangle's two edges. Returns (t, marginal)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -((o - c00) @ n) / (d @ n)
    p = o + t[:, None] * d
    a = (p - c00) @ e1 / (e1 @ e1)
    b = (p - c00) @ e2 / (e2 @ e2)
    inside = (a >= 0) & (a <= 1) & (b >= 0) & (b <= 1) & (t > tmin) & np.isfinite(t)
    edge = np.minimum(np.minimum(np.abs(a), np.abs(a - 1)), np.minimum(np.abs(b), np.abs(b - 1)))
    cosine = np.abs(d @ n) / np.linalg.norm(d, axis=1)
    marginal = (edge < 1e-6) | (cosine < 1e-6) | (np.abs(t - tmin) < 1e-6)
    return np.where(inside, t, np.inf), marginal


def compact(alive, *arrays):
    """Each array's rows where `alive` is set, in order (the reflected rays
    trace.resolve.resolve_range emits)."""
    return [np.compress(alive, a, axis=0) for a in arrays]


def pick(t_o, t_m, t_a):
    """Twin of trace.resolve._pick: of the finite candidates (object t, mirror triangle t and
    analytic mirror t, mirrors' t scaled by MIRROR_TIE), the nearest; ties go to the analytic
    mirror, then the mirror triangle. 0 object, 1 mirror triangle, 2 analytic, -1 miss."""
    cands = [(float(t_a) * MIRROR_TIE, 0, 2), (float(t_m) * MIRROR_TIE, 1, 1),
             (float(t_o), 2, 0)]
    finite = [c for c in cands if math.isfinite(c[0])]
    return min(finite)[2] if finite else -1


def planar_units(kind, params):
    """Twin of trace.resolve.planar_units: each planar mirror's plane normal over its length,
    in float64 (rows of other mirrors: nan)."""
    unit = np.full((len(kind), 3), np.nan)
    for k in range(len(kind)):
        if kind[k] == PLANAR:
            g = params[k, 0:3].astype(np.float64)
            unit[k] = g / np.sqrt(g @ g)
    return unit


def resolve(origins, dirs, weight, slot, t_o, p_o, u_o, v_o, t_m, p_m, u_m, v_m, t_a, k_a,
            corners, uvs, normals, material, surface, m_corners, m_normals, m_surface, m_kind,
            m_params, m_refl, m_base, n_objects, mat_i, mat_f, texels, light_f, shading,
            ambient, background, follow, color):
    """Twin of trace.resolve.resolve_range: one wave of Whitted tracing, ray by ray in float64.

    A miss adds weight * background; an object adds weight * its surface color; a mirror
    adds weight * (1 - r) * base and, if `follow`, emits the reflected ray
    r = d - 2 (d.n) n (n the shading normal facing the ray, unit), starting eps along r off
    the surface (eps = 1e-4 (1 + max |p|) measured along the geometric normal, the cosine
    floored at 0.01), with weight * r; it lives on if any weight channel is positive.
    Returns (color (in place), hit_t, hit_surface, alive, next_o, next_d, next_w)."""
    n = origins.shape[0]
    hit_t = np.zeros(n)
    hit_surface = np.zeros(n, np.int64)
    alive = np.zeros(n, bool)
    next_o = np.full((n, 3), np.nan)
    next_d = np.full((n, 3), np.nan)
    next_w = np.full((n, 3), np.nan)
    for i in range(n):
        o = origins[i].astype(np.float64)
        d = dirs[i].astype(np.float64)
        s = slot[i]
        which = pick(t_o[i], t_m[i], t_a[i])
        if which < 0:
            hit_t[i], hit_surface[i] = np.inf, -1
            color[s] += weight[i] * background
            continue
        if which == 0:
            t, tri = float(t_o[i]), p_o[i]
            bary = _bary(u_o[i], v_o[i])
            p = o + t * d
            uv = bary @ uvs[tri]
            nrm = bary @ normals[tri]
            hit_t[i], hit_surface[i] = t, surface[tri]
            color[s] += weight[i] * surface_color(material[tri], uv[0], uv[1], p, nrm, d,
                                                  mat_i, mat_f, texels, light_f, shading,
                                                  ambient)
            continue
        if which == 1:
            t, tri = float(t_m[i]), p_m[i]
            k = m_surface[tri] - n_objects
            c = m_corners[tri].astype(np.float64)
            g = np.cross(c[1] - c[0], c[2] - c[0])
            bary = _bary(u_m[i], v_m[i])
            nrm = bary @ m_normals[tri].astype(np.float64)
            p = o + t * d
        else:
            t, k = float(t_a[i]), k_a[i]
            prm = m_params[k]
            p = o + t * d
            if m_kind[k] == PLANAR:
                g = prm[0:3].copy()
            elif m_kind[k] == SPHERE:
                g = p - prm[0:3]
            else:  # cylinder: from the axis, perpendicular to it
                rel = p - prm[0:3]
                g = rel - (rel @ prm[3:6]) * prm[3:6]
            nrm = g.copy()
        hit_t[i], hit_surface[i] = t, n_objects + k
        color[s] += weight[i] * (1.0 - m_refl[k].astype(np.float64)) * m_base[k]
        if not follow:
            continue
        g = -g if g @ d > 0 else g
        nrm = -nrm if nrm @ d > 0 else nrm
        g, nrm = g / np.linalg.norm(g), nrm / np.linalg.norm(nrm)
        r = d - 2.0 * (d @ nrm) * nrm
        r /= np.linalg.norm(r)
        eps = 1e-4 * (1.0 + np.abs(p).max())
        next_o[i] = p + eps / max(r @ g, 1e-2) * r
        next_d[i] = r
        next_w[i] = weight[i] * m_refl[k]
        alive[i] = bool(np.any(next_w[i] > 0))
    return color, hit_t, hit_surface, alive, next_o, next_d, next_w


def analytic_nearest(o, d, tfar, kind, params, tmin):
    """The closed forms of every analytic mirror together (the twin of
    trace.analytic.intersect_range, which a wave uses, and of trace.analytic.intersect_rows,
    which the primary wave uses inside the mirrors' screen boxes): (t, mirror or -1,
    marginal), marginal where the closed forms' own ambiguity (tangents, rims, edges, near
    ties) allows either answer."""
    o64, d64, p = o.astype(np.float64), d.astype(np.float64), params
    n, k = len(o), len(kind)
    all_t = np.full((n, k), np.inf)
    marginal = np.zeros(n, bool)
    for i in range(k):
        if kind[i] == SPHERE:
            ti, disc, roots = sphere_closed_form(o64, d64, p[i, :3], p[i, 3], tmin)
            scale = p[i, 3] ** 2 / np.einsum("rk,rk->r", d64, d64)
            marginal |= (disc >= 0) & (disc < 1e-8 * scale)
            marginal |= (np.abs(roots - tmin) < 1e-6).any(axis=1)
        elif kind[i] == CYLINDER:
            ti, m = cylinder_closed_form(o64, d64, p[i, :3], p[i, 3:6], p[i, 6], p[i, 7], tmin)
            marginal |= m
        elif kind[i] == PLANAR:
            c = p[i, 4:16].reshape(4, 3)
            ti, m = quad_closed_form(o64, d64, p[i, :3], c[0], c[1] - c[0], c[3] - c[0], tmin)
            marginal |= m
        else:
            continue
        all_t[:, i] = ti
    far = tfar.astype(np.float64)[:, None]
    with np.errstate(invalid="ignore"):  # inf - inf where nothing is hit and tfar is inf
        marginal |= (np.abs(all_t - far) < 1e-6 * far).any(axis=1)
    all_t[all_t >= far] = np.inf
    best = all_t.min(axis=1) if k else np.full(n, np.inf)
    which = np.where(np.isfinite(best), all_t.argmin(axis=1), -1) if k else np.full(n, -1)
    if k > 1:
        srt = np.sort(all_t, axis=1)
        with np.errstate(invalid="ignore"):
            gap = np.where(np.isfinite(srt[:, 1]), srt[:, 1] - srt[:, 0], np.inf)
        marginal |= gap < 1e-6 * np.abs(srt[:, 1])
    return best, which, marginal


def embreex_hits(corners, o, d, tfar):
    """Nearest triangle hits by the embreex binding, Embree's reference (the kernels' hits
    equal its to the bit: test_embree_bruteforce.py): (t (inf on a miss), prim, u, v)."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    n = len(o)
    if len(corners) == 0 or n == 0:
        return np.full(n, np.inf), np.full(n, -1), np.zeros(n), np.zeros(n)
    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, np.ascontiguousarray(corners, np.float32))
    res = scene.run(np.ascontiguousarray(o, np.float32), np.ascontiguousarray(d, np.float32),
                    dists=np.ascontiguousarray(tfar, np.float32).copy(), output=1)
    hit = res["primID"] >= 0
    return (np.where(hit, res["tfar"], np.inf).astype(np.float32), res["primID"],
            res["u"], res["v"])


def wave(counts, seg_len, rays, tfar, obj_corners, mirror_corners, kind, params, surfaces,
         follow, bounce, near, color):
    """Twin of one wave of trace.wave.trace_segments (its _wave on every segment) on given
    rays: segment k holds rays k * seg_len .. k * seg_len + counts[k] - 1 of rays (origins,
    dirs, weights, slots). Hits: Embree's
    reference (embreex) for object and mirror triangles, the closed forms for analytic
    mirrors; shading: `resolve`; each segment's reflected rays in order. Returns (rows,
    color, hit_t, hit_surface, alive, emitted per segment (origins, dirs, weights, slots),
    depth (hit_t + near in float32, inf on a miss; bounce 0), marginal)."""
    origins, dirs, weight, slot = rays
    rows = np.concatenate([np.arange(k * seg_len, k * seg_len + c) for k, c in enumerate(counts)])
    o, d = origins[rows], dirs[rows]
    far = np.full(len(rows), tfar, np.float32)
    t_o, p_o, u_o, v_o = embreex_hits(obj_corners, o, d, far)
    t_m, p_m, u_m, v_m = embreex_hits(mirror_corners, o, d, far)
    t_a, k_a, marginal = analytic_nearest(o, d, far, kind, params, 0.0)
    t_a = t_a.astype(np.float32)  # the kernels keep t in float32 between the steps
    # a mirror's t (scaled by MIRROR_TIE) within the closed forms' error of another's t:
    # either may win
    for a, b in ((t_o, t_a), (t_m, t_a)):
        with np.errstate(invalid="ignore"):
            marginal |= np.isfinite(b) & (np.abs(a.astype(float) - MIRROR_TIE * b)
                                          <= 1e-5 * np.abs(b))
    color, hit_t, hit_surface, alive, next_o, next_d, next_w = resolve(
        o, d, weight[rows], slot[rows], t_o, p_o, u_o, v_o, t_m, p_m, u_m, v_m, t_a, k_a,
        *surfaces[:20], follow, color)  # (not the kernel's planar_units: worked out here)
    emitted, start = [], 0
    for c in counts:
        part = slice(start, start + c)
        emitted.append(compact(alive[part], next_o[part], next_d[part], next_w[part],
                               slot[rows][part]))
        start += c
    with np.errstate(invalid="ignore"):
        depth = np.where(hit_surface >= 0, hit_t.astype(np.float32) + np.float32(near), np.inf)
    return rows, color, hit_t, hit_surface, alive, emitted, depth, marginal


# ==================================================================================== maps


def image_sample(image, u, v, bilinear):
    """Twin of maps.cube.image_sample: the color at (u, v) in [0, 1]^2 of an (R, R, 3)
    image, nearest texel or bilinear between texel centers with the edges clamped (scipy's
    'nearest' boundary mode)."""
    res = image.shape[0]
    img = np.asarray(image, np.float64)
    if not bilinear or res == 1:
        x = min(max(int(u * res), 0), res - 1)
        y = min(max(int(v * res), 0), res - 1)
        return img[y, x]
    y, x = min(max(v * res - 0.5, 0.0), res - 1.0), min(max(u * res - 0.5, 0.0), res - 1.0)
    return np.array([map_coordinates(img[:, :, c], [[y], [x]], order=1, mode="nearest")[0]
                     for c in range(3)])


def cube_face_coords(r):
    """Twin of maps.cube.cube_face_coords: the face of r's major axis (x before y before z
    on ties), and where the face's own Camera (maps.cube.face_camera) projects the point r
    seen from the origin: (face, u, v) in [0, 1]^2, v down."""
    from reflectcli.maps.cube import face_camera

    r = np.asarray(r, np.float64)
    a = np.abs(r)
    axis = 0 if a[0] >= a[1] and a[0] >= a[2] else (1 if a[1] >= a[2] else 2)
    face = 2 * axis + (0 if r[axis] > 0 else 1)
    cam = face_camera(face, np.zeros(3), 1, 0.1, 10.0)
    clip = cam.projection_matrix() @ cam.view_matrix() @ np.append(r, 1.0)
    x, y = clip[0] / clip[3], clip[1] / clip[3]
    return face, (x + 1.0) * 0.5, (1.0 - y) * 0.5


def cube_sample(faces, r, bilinear):
    """Twin of maps.cube.cube_sample: image_sample on the face cube_face_coords picks."""
    face, u, v = cube_face_coords(r)
    return image_sample(faces[face], u, v, bilinear)


def sphere_coords(r):
    """Twin of maps.sphere.sphere_coords: (s, t) = (rx, ry) / |r + (0, 0, 1)| for unit r,
    texel coordinates ((s + 1) / 2, (1 - t) / 2); r = (0, 0, -1) goes to the rim at (1, 0.5)."""
    r = np.asarray(r, np.float64) / np.linalg.norm(r)
    m = np.linalg.norm(r + np.array([0.0, 0.0, 1.0]))
    if m == 0.0:
        return 1.0, 0.5
    return (r[0] / m + 1.0) * 0.5, (1.0 - r[1] / m) * 0.5


def sphere_sample(image, r, bilinear):
    """Twin of maps.sphere.sphere_sample."""
    u, v = sphere_coords(r)
    return image_sample(image, u, v, bilinear)


def sphere_from_cube(faces, resolution):
    """Twin of maps.sphere._sphere_from_cube: per texel center (s, t) of the disk, the mirror
    ball's normal n = (s, t, sqrt(1 - s^2 - t^2)) reflects the viewer direction v = +z into
    r = 2 (n.v) n - v, sampled bilinearly in the cube map; black outside the disk."""
    out = np.zeros((resolution, resolution, 3))
    for j in range(resolution):
        for i in range(resolution):
            s = 2.0 * (i + 0.5) / resolution - 1.0
            t = 1.0 - 2.0 * (j + 0.5) / resolution
            if s * s + t * t > 1.0:
                continue
            n = np.array([s, t, math.sqrt(1.0 - s * s - t * t)])
            r = 2.0 * n[2] * n - np.array([0.0, 0.0, 1.0])
            out[j, i] = cube_sample(faces, r, True)
    return out


def box_exit(p, r, lo, hi):
    """Twin of maps.lookup.box_exit: the t where p + t r leaves the box [lo, hi] (p clamped
    into it), found by bisection on 'is inside'; -1 if p lies outside the box by more than
    1e-4 of its size."""
    p, r = np.asarray(p, np.float64), np.asarray(r, np.float64)
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    tol = 1e-4 * (hi - lo)
    if np.any(p < lo - tol) or np.any(p > hi + tol):
        return -1.0
    q = np.clip(p, lo, hi)
    if not np.any(r != 0):
        return np.inf

    def inside(t):
        x = q + t * r
        return bool(np.all((x >= lo) & (x <= hi)))

    a, b = 0.0, 1.0
    while inside(b):
        a, b = b, 2.0 * b
    for _ in range(200):
        mid = 0.5 * (a + b)
        if mid in (a, b):
            break
        a, b = (mid, b) if inside(mid) else (a, mid)
    return a


def add_reflections(rgb, tri, b1, b2, surface_ids, surface, corners, normals, kind, params,
                    refl, eye, capture, lo, hi, parallax, map_kind, faces, sphere, bilinear):
    """Twin of maps.lookup._add: on the pixels of `surface`, the point p and normal n of the
    reflector (exact for planes, spheres, cylinders, else interpolated), the view reflected
    about n (two-sided), optionally replaced by the direction from the capture point to where
    it leaves the proxy box, and refl * the map's color in that direction added to rgb."""
    out = np.asarray(rgb, np.float64).copy()
    h, w = tri.shape
    for y in range(h):
        for x in range(w):
            if surface_ids[y, x] != surface:
                continue
            t = tri[y, x]
            bary = _bary(b1[y, x], b2[y, x])
            p = bary @ corners[t].astype(np.float64)
            if kind == PLANAR:
                n = params[0:3].copy()
            elif kind == SPHERE:
                n = p - params[0:3]
            elif kind == CYLINDER:
                rel = p - params[0:3]
                n = rel - (rel @ params[3:6]) * params[3:6]
            else:
                n = bary @ normals[t].astype(np.float64)
            n /= np.linalg.norm(n)
            v = (eye - p) / np.linalg.norm(eye - p)
            if n @ v < 0:
                n = -n
            r = 2.0 * (n @ v) * n - v
            if parallax:
                te = box_exit(p, r, lo, hi)
                if te > 0.0:
                    r = p + te * r - capture
            c = cube_sample(faces, r, bilinear) if map_kind == 0 else sphere_sample(
                sphere, r, bilinear)
            out[y, x] += np.asarray(refl, np.float64) * c
    return out


def surface_intersect(triangle, camera, reflection, origin, corners, normal, offset):
    """Twin of maps.surface._intersect: per pixel with a triangle, the camera's pixel-center
    ray (Camera.pixel_directions) turned by the reflection, from `origin`, solved against the
    triangle's plane as the 3x3 system o + t d = v0 + u e1 + v e2 (numpy's solver). A hit
    needs a well-conditioned system (|det| > 1e-12 |e1| |e2| |d|), t > 0 and t beyond where
    the ray crosses the mirror plane (normal, offset). Returns (hit, b1, b2, depth) with
    barycentrics clamped to [-1, 2]."""
    h, w = triangle.shape
    dirs = camera.pixel_directions(1)[:, :, 0] @ np.asarray(reflection, np.float64)[:3, :3].T
    hit = triangle.copy()
    b1 = np.zeros((h, w))
    b2 = np.zeros((h, w))
    depth = np.full((h, w), np.inf)
    o = np.asarray(origin, np.float64)
    normal = np.asarray(normal, np.float64)
    side = normal @ o + offset
    for y in range(h):
        for x in range(w):
            t = triangle[y, x]
            if t < 0:
                continue
            c = corners[t].astype(np.float64)
            d = dirs[y, x]
            e1, e2 = c[1] - c[0], c[2] - c[0]
            a = np.stack([-d, e1, e2], axis=1)
            if abs(np.linalg.det(a)) <= 1e-12 * np.linalg.norm(e1) * np.linalg.norm(
                    e2) * np.linalg.norm(d):
                hit[y, x] = -1
                continue
            dist, u, v = np.linalg.solve(a, o - c[0])
            dn = normal @ d
            crossing = -side / dn if dn != 0.0 else np.inf
            if not (dist > 0.0 and dist > crossing):
                hit[y, x] = -1
                continue
            b1[y, x], b2[y, x] = min(max(u, -1.0), 2.0), min(max(v, -1.0), 2.0)
            depth[y, x] = dist
    return hit, b1, b2, depth


def project(depth, w, near, box, width, height):
    """Twin of maps.warp._project: each zexel (u, v) with depth d maps to clip = W (u, v, 1,
    1/d) (delta = 0 for d = inf: a direction); its eye depth in the target camera is
    d * clip_w; kept (screen position, depth) if in front of the near plane (a direction: if
    clip_w > 0) and on screen within `box` = (xmin, xmax, ymin, ymax), else sx = NaN.
    Returns (sx, sy, z, row_lo, row_hi) with per map row the first and last screen row."""
    mh, mw = depth.shape
    sx = np.full(mh * mw, np.nan)
    sy = np.full(mh * mw, np.nan)
    z = np.full(mh * mw, np.nan)
    row_lo = np.full(mh, 1 << 40)
    row_hi = np.full(mh, -1)
    xmin, xmax, ymin, ymax = box
    for v in range(mh):
        for u in range(mw):
            k = v * mw + u
            d = float(depth[v, u])
            if d == np.inf:
                clip = w @ np.array([u, v, 1.0, 0.0])
                zz, ok = np.inf, clip[3] > 0
            elif d > 0:
                clip = w @ np.array([u, v, 1.0, 1.0 / d])
                zz = d * clip[3]
                ok = zz > near
            else:
                ok = False
            if not ok:
                continue
            x = (clip[0] / clip[3] + 1.0) * 0.5 * width
            y = (1.0 - clip[1] / clip[3]) * 0.5 * height
            if not (xmin <= x < xmax and ymin <= y < ymax):
                continue
            sx[k], sy[k], z[k] = x, y, zz
            row = math.floor(np.float32(y))
            row_lo[v] = min(row_lo[v], row)
            row_hi[v] = max(row_hi[v], row)
    return sx, sy, z, row_lo, row_hi


def adaptive_radii(sx, sy, z, mh, mw):
    """Twin of maps.warp._adaptive: per zexel, the largest screen step (x or y) to a 4-
    neighbour of the same surface (depths within 5% of the smaller), halved and rounded up
    less a half pixel, capped at 3; 0 for steps of at most a pixel or no such neighbour."""
    radii = np.zeros(mh * mw, np.int64)
    for v in range(mh):
        for u in range(mw):
            k = v * mw + u
            if np.isnan(sx[k]):
                continue
            steps = [0.0]
            for uu, vv in ((u + 1, v), (u, v + 1), (u - 1, v), (u, v - 1)):
                if not (0 <= uu < mw and 0 <= vv < mh):
                    continue
                q = vv * mw + uu
                with np.errstate(invalid="ignore"):  # inf - inf: two directions
                    same = abs(z[q] - z[k]) <= 0.05 * min(z[q], z[k])
                if np.isnan(sx[q]) or not same:
                    continue
                steps += [abs(sx[q] - sx[k]), abs(sy[q] - sy[k])]
            reach = max(steps)
            radii[k] = min(3, math.ceil(reach / 2 - 0.5)) if reach > 1.0 else 0
    return radii


def splat_zbuffer(sx, sy, z, radii, mw, stencil):
    """Twin of maps.warp._splat / _write (z-buffer mode): the visibility rule as documented,
    in two passes: per pixel, the nearest depth among the zexels that reach it; then, of
    those within SAME_SURFACE of it, the one landing nearest the pixel center (ties to the
    lower index). The kernel does it in one pass; the two agree where each surface keeps its
    zexels' depths within SAME_SURFACE / 2."""
    from reflectcli.maps.warp import SAME_SURFACE

    h, w = stencil.shape
    hits = {}
    for k in range(sx.size):
        if np.isnan(sx[k]):
            continue
        px, py, r = int(np.floor(sx[k])), int(np.floor(sy[k])), int(radii[k])
        for y in range(py - r, py + r + 1):
            for x in range(px - r, px + r + 1):
                if 0 <= y < h and 0 <= x < w and stencil[y, x]:
                    d = (np.float32(sx[k]) - x - 0.5) ** 2 + (np.float32(sy[k]) - y - 0.5) ** 2
                    hits.setdefault((y, x), []).append((z[k], d, k))
    best = np.full((h, w), -1)
    for (y, x), cands in hits.items():
        front = min(c[0] for c in cands)
        same = [c for c in cands if c[0] <= front * (1 + SAME_SURFACE)]
        best[y, x] = min(same, key=lambda c: (c[1], c[2]))[2]
    return best


def splat_spread(sx, sy, z, radius, stencil):
    """Twin of maps.warp's one-pixel splat followed by `spread` (_splat_pixels, _spread,
    z-buffer mode, one map): first every pixel of the screen keeps, of the zexels landing in
    it, one of the nearest depth's surface (`splat_zbuffer` with radius 0, no stencil); then
    each stencil pixel looks at the kept zexels in its (2 radius + 1)^2 square: the nearest
    is the one of least (depth, index), and the front surface is those within SAME_SURFACE
    of its depth (or equal to it). The pixel keeps its own zexel if that is on it, else
    takes, of the squares of radius 1, 2, ..., radius around it, the first whose nearest
    zexel is on the front surface: that nearest. Returns (depth, id), -1 / inf where none."""
    from reflectcli.maps.warp import SAME_SURFACE

    h, w = stencil.shape
    kept = splat_zbuffer(sx, sy, z, np.zeros(sx.size, np.int64), None, np.ones((h, w), bool))
    best_z = np.full((h, w), np.inf, np.float32)
    best_id = np.full((h, w), -1)

    def nearest(y, x, r):
        square = [kept[yy, xx] for yy in range(y - r, y + r + 1)
                  for xx in range(x - r, x + r + 1)
                  if 0 <= yy < h and 0 <= xx < w and kept[yy, xx] >= 0]
        return min(square, key=lambda k: (z[k], k)) if square else -1

    for y in range(h):
        for x in range(w):
            if not stencil[y, x] or nearest(y, x, radius) < 0:
                continue
            front = z[nearest(y, x, radius)]

            def on_front(k, front=front):
                return z[k] <= front * (1 + SAME_SURFACE) or z[k] == front

            own = kept[y, x]
            if own >= 0 and on_front(own):
                choice = own
            else:
                choice = next(nearest(y, x, r) for r in range(1, radius + 1)
                              if nearest(y, x, r) >= 0 and on_front(nearest(y, x, r)))
            best_id[y, x] = choice
            best_z[y, x] = z[choice]
    return best_z, best_id


def splat_sequential(maps, stencil, ordered):
    """Twin of maps.warp._splat / _write in both modes: one thread, no bands, no row
    skipping; maps in slot order, each one's zexels in its runs' order, each zexel over the
    stencil pixels of its (2r+1)^2 square. `maps`: list of (sx, sy, z, radii, runs, mw).

    Rule at a pixel, against the zexel kept so far (depth bz, squared distance to the center
    bd, id c): an empty pixel, a zexel more than SAME_SURFACE nearer, or (ordered) one from
    the same map takes it; else one within SAME_SURFACE of bz (or equal to it, for two at
    infinity) takes it if it lands nearer the center, ties to the lower id.
    Returns (best depth, best id) with ids slot * stride + zexel index."""
    from reflectcli.maps.warp import SAME_SURFACE

    h, w = stencil.shape
    stride = max(m[0].size for m in maps)
    best_z = np.full((h, w), np.inf, np.float32)
    best_d = np.full((h, w), np.inf, np.float32)
    best_id = np.full((h, w), -1, np.int64)
    for slot, (sx, sy, z, radii, runs, mw) in enumerate(maps):
        for v, first, stop, step in runs:
            for u in range(first, stop, step):
                k = v * mw + u
                if np.isnan(sx[k]):
                    continue
                fx, fy, r = np.float32(sx[k]), np.float32(sy[k]), int(radii[k])
                px, py = math.floor(fx), math.floor(fy)
                for y in range(py - r, py + r + 1):
                    for x in range(px - r, px + r + 1):
                        if not (0 <= y < h and 0 <= x < w and stencil[y, x]):
                            continue
                        dk = np.float32((fx - x - 0.5) ** 2 + (fy - y - 0.5) ** 2)
                        ident = slot * stride + k
                        c, bz, bd = best_id[y, x], best_z[y, x], best_d[y, x]
                        takes = c < 0 or z[k] < bz * (1.0 - SAME_SURFACE) or (
                            ordered and c // stride == slot)
                        same_surface = z[k] <= bz * (1.0 + SAME_SURFACE) or z[k] == bz
                        nearer = dk < bd or (dk == bd and ident < c)
                        if takes or (same_surface and nearer):
                            best_z[y, x], best_d[y, x], best_id[y, x] = z[k], dk, ident
    return best_z, best_id


# ================================================================================= virtual


def _reflect_across(q, j, n):
    """q mirrored across the plane through j with unit normal n."""
    return q - 2.0 * ((q - j) @ n) * n


def mirror_on_circle(e, q, c, r, axis=None):
    """Twin of virtual.direct._mirror_on_circle / _circle_reflection / _circle_law / _many:
    (Q', hidden) for a sphere (axis None) or a cylinder (unit axis; the problem is solved in
    the cross-section through Q). Fermat: the reflection point J on a convex circle minimizes
    the path length |E - J| + |J - Q| over the arc between the directions of E and Q (scipy's
    bounded minimizer). Hidden (the segment E -> Q enters the circle first, a root of the
    ray-circle quadratic in (0, 1)): J is that entry point. Q' = Q mirrored across the tangent
    plane at J. Points (or an eye) inside keep Q' = Q."""
    e, q, c = (np.asarray(x, np.float64) for x in (e, q, c))
    ev, qv = e - c, q - c
    if axis is not None:
        axis = np.asarray(axis, np.float64)
        ev = ev - (ev @ axis) * axis
        qv = qv - (qv @ axis) * axis
    if np.linalg.norm(qv) <= r or np.linalg.norm(ev) <= r:
        return q.copy(), False
    x_axis = ev / np.linalg.norm(ev)
    y_vec = qv - (qv @ x_axis) * x_axis
    y_axis = y_vec / np.linalg.norm(y_vec) if np.linalg.norm(y_vec) >= 1e-12 * np.linalg.norm(
        qv) else np.zeros(3)
    # hidden: |ev + s (qv - ev)| = r for some s in (0, 1), first root
    dv = qv - ev
    roots = np.roots([dv @ dv, 2 * (ev @ dv), ev @ ev - r * r])
    real = [s.real for s in roots if abs(s.imag) < 1e-12 * max(1.0, abs(s.real))]
    first = min(real) if real else 2.0
    if 0.0 < first < 1.0:
        jv = ev + first * dv
        n = jv / np.linalg.norm(jv)
        return _reflect_across(q - c, r * n, n) + c, True
    if not np.any(y_axis):
        n = x_axis
    else:
        phi = math.atan2(qv @ y_axis, qv @ x_axis)

        def length(theta):
            j = r * (math.cos(theta) * x_axis + math.sin(theta) * y_axis)
            return np.linalg.norm(ev - j) + np.linalg.norm(qv - j)

        theta = minimize_scalar(length, bounds=(0.0, phi), method="bounded",
                                options={"xatol": 1e-12}).x
        n = math.cos(theta) * x_axis + math.sin(theta) * y_axis
    return _reflect_across(q - c, r * n, n) + c, False  # n is across the axis


def profile_point(profile, normals, t):
    """Twin of virtual.direct._profile_at: point and unit normal at t along the polyline."""
    s = min(int(math.floor(t)), len(profile) - 2)
    a = t - s
    j = (1 - a) * profile[s] + a * profile[s + 1]
    n = (1 - a) * normals[s] + a * normals[s + 1]
    return j, n / np.linalg.norm(n)


def profile_law(profile, normals, t, e, q):
    """Twin of virtual.direct._law: the sine of the angle from n to u_E plus that from n to
    u_Q (unit vectors from J toward E and Q, 2-D): zero where n bisects them."""
    j, n = profile_point(profile, normals, t)
    ue, uq = (e - j) / max(np.linalg.norm(e - j), 1e-300), (q - j) / max(
        np.linalg.norm(q - j), 1e-300)
    def cross(a, b):  # 2-D cross product
        return a[0] * b[1] - a[1] * b[0]

    return float(cross(n, ue) + cross(n, uq))


def profile_one(q3, e3, profile, normals):
    """Twin of virtual.direct._profile_one / _profile_many (local frame, y the extrusion).

    In the (x, z) section: hidden if the segment E -> Q crosses a profile segment (then J is
    the first crossing); else J is the root of profile_law in the first profile segment whose
    ends bracket a sign change (scipy's brentq), or, if none does, the profile vertex with the
    smallest |law|. Q' is Q mirrored across the line through J with J's normal (2-D)."""
    profile, normals = np.asarray(profile, np.float64), np.asarray(normals, np.float64)
    e, q = np.array([e3[0], e3[2]], np.float64), np.array([q3[0], q3[2]], np.float64)
    best_t, param = 2.0, -1.0
    for s in range(len(profile) - 1):
        a, b = profile[s], profile[s + 1]
        m = np.array([q - e, a - b]).T  # e + t (q - e) = a + u (b - a)
        if np.linalg.det(m) == 0:
            continue
        t, u = np.linalg.solve(m, a - e)
        if 0.0 < t < best_t and 0.0 <= u <= 1.0:
            best_t, param = t, s + u
    hidden = param >= 0.0
    if not hidden:
        law = [profile_law(profile, normals, float(s), e, q) for s in range(len(profile))]
        param = float(np.argmin(np.abs(law)))
        for s in range(len(profile) - 1):
            if (law[s] > 0) != (law[s + 1] > 0):
                param = brentq(lambda t: profile_law(profile, normals, t, e, q), s, s + 1,
                               xtol=1e-14) if law[s] != 0 and law[s + 1] != 0 else float(
                    s if law[s] == 0 else s + 1)
                break
    j, n = profile_point(profile, normals, param)
    qq = _reflect_across(q, j, n)
    return np.array([qq[0], q3[1], qq[1]]), hidden


def mirror_boxes(surface, n_objects, n_mirrors):
    """Twin of virtual.compose.mirror_boxes: per mirror its pixel count and the box (y0, y1,
    x0, x1) of its pixels, (0, 0, 0, 0) if none."""
    counts = np.zeros(n_mirrors, np.int64)
    boxes = np.zeros((n_mirrors, 4), np.int64)
    for k in range(n_mirrors):
        ys, xs = np.nonzero(surface == n_objects + k)
        counts[k] = ys.size
        if ys.size:
            boxes[k] = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    return counts, boxes


def part_stencil(triangle, surface, sid, first, faces, count):
    """Twin of virtual.compose.part_stencil: pixels of surface sid whose triangle is one of
    the reflector's faces (first .. first + count - 1) listed in `faces` (face indices)."""
    face = triangle.astype(np.int64) - first
    ok = (face >= 0) & (face < count)
    return (surface == sid) & ok & np.isin(np.where(ok, face, -1), faces)


def faces_behind(screen, depth, triangle, local):
    """Twin of virtual.view._faces_behind (PartView.faces_behind; view.face_behind one
    point at a time, as parts._gather_parts takes it): pixels by flooring the
    finite screen positions of points in front of the eye, kept on the image; where the
    point is deeper than `depth` there, the part's face under it (local[triangle]), else
    -1."""
    h, w = depth.shape
    out = np.full(len(screen), -1, np.int64)
    for i, (x, y, z) in enumerate(np.asarray(screen, np.float64)):
        if not (np.isfinite(x) and np.isfinite(y) and z > 0):
            continue
        xi, yi = math.floor(x), math.floor(y)
        if 0 <= xi < w and 0 <= yi < h and z > depth[yi, xi]:
            out[i] = local[triangle[yi, xi]]
    return out


def part_views(triangle, local, size):
    """Twin of virtual.view.part_views: per part p, (its face under each pixel, local[p]
    indexed by the item buffer (-1 reads the last entry), those >= 0, and the ids
    ty * (W // size + 1) + tx of the tiles holding its pixels, ascending)."""
    w = triangle.shape[1]
    out = []
    for p in range(local.shape[0]):
        hidden = local[p][triangle]
        ys, xs = np.nonzero(hidden >= 0)
        out.append((hidden, hidden >= 0, np.unique((ys // size) * (w // size + 1) + xs // size)))
    return out


def gather_corners(virtual, hidden, corner_index, surface, n_objects):
    """Twin of virtual.compose.gather_corners (and of its per-triangle step
    raster.rasterize.gather.gather_triangle, which rasterize_passes runs as it draws):
    (corners (T, 3, 3) float32, flags (T,))."""
    corners = virtual[corner_index].astype(np.float32)
    flags = np.where(surface >= n_objects, FLAG_MIRROR, 0).astype(np.uint8)
    flags[hidden[corner_index].all(axis=1)] |= FLAG_SKIP
    return corners, flags


def fill_cracks(colors, covered, stencil):
    """Twin of virtual.compose.fill_cracks (the whole image: the box is an optimisation), in
    place: a stencil pixel no fragment covered, with both neighbours across it covered
    (above and below, or left and right), takes their mean, summed in float64 in the order
    above, below, left, right."""
    h, w = covered.shape
    ys, xs = np.nonzero(stencil & ~covered)
    total = np.zeros((ys.size, 3), np.float64)
    count = np.zeros(ys.size, np.int64)
    for dy, dx in ((1, 0), (0, 1)):
        pair = (ys >= dy) & (xs >= dx) & (ys + dy < h) & (xs + dx < w)
        k = np.flatnonzero(pair)
        k = k[covered[ys[k] - dy, xs[k] - dx] & covered[ys[k] + dy, xs[k] + dx]]
        total[k] += colors[ys[k] - dy, xs[k] - dx].astype(np.float64)
        total[k] += colors[ys[k] + dy, xs[k] + dx].astype(np.float64)
        count[k] += 2
    filled = count > 0
    colors[ys[filled], xs[filled]] = (total[filled] / count[filled][:, None]).astype(np.float32)


def reflector_grid(triangle, b1, b2, corners, normals, eye):
    """Twin of virtual.refine._grid: per covered pixel the interpolated point Q and the eye
    ray's direction reflected about the interpolated unit normal; NaN elsewhere."""
    h, w = triangle.shape
    q = np.full((h, w, 3), np.nan)
    r = np.full((h, w, 3), np.nan)
    for y in range(h):
        for x in range(w):
            t = triangle[y, x]
            if t < 0:
                continue
            bary = _bary(b1[y, x], b2[y, x])
            p = bary @ corners[t]
            n = bary @ normals[t]
            n = n / max(np.linalg.norm(n), 1e-30)
            d = (p - eye) / np.linalg.norm(p - eye)
            q[y, x], r[y, x] = p, d - 2.0 * (d @ n) * n
    return q, r


def mirror_rays(triangle, mirror, drawn, clip_from_world, corners, normals, eye, box):
    """Twin of virtual.refine.mirror_rays: over the screen box (y0, y1, x0, x1), at each
    mirror pixel with a triangle, the perspective-correct barycentrics of its center among
    the triangle's drawn corners (float64: clip space, screen edge functions, then through
    1/w), and R as reflector_grid makes it; NaN at the box's other pixels, the rest NaN."""
    h, w = triangle.shape
    y0, y1, x0, x1 = box
    r = np.full((h, w, 3), np.nan)
    for y in range(y0, y1):
        for x in range(x0, x1):
            t = triangle[y, x]
            if t < 0 or not mirror[y, x]:
                continue
            clip = np.c_[drawn[t].astype(np.float64), np.ones(3)] @ clip_from_world.T
            sx = (clip[:, 0] / clip[:, 3] + 1) * 0.5 * w  # screen
            sy = (1 - clip[:, 1] / clip[:, 3]) * 0.5 * h
            cx, cy = x + 0.5, y + 0.5
            lam = np.array([(sx[b] - sx[a]) * (cy - sy[a]) - (sy[b] - sy[a]) * (cx - sx[a])
                            for a, b in ((1, 2), (2, 0), (0, 1))])
            bary = lam / clip[:, 3]
            bary = bary / bary.sum()
            p = bary @ corners[t]
            n = bary @ normals[t]
            n = n / max(np.linalg.norm(n), 1e-30)
            d = (p - eye) / np.linalg.norm(p - eye)
            r[y, x] = d - 2.0 * (d @ n) * n
    return r


def grid_sample(inside, q, r, sx, sy):
    """Twin of virtual.refine._sample_slope's values: bilinear Q and R at screen point
    (sx, sy) over the pixel centers inside the part, the missing corners' weight given to the others
    (renormalized), R normalized; None if no corner inside carries weight."""
    h, w = inside.shape
    fx, fy = sx - 0.5, sy - 0.5
    x0, y0 = math.floor(fx), math.floor(fy)
    ax, ay = fx - x0, fy - y0
    corners = [(x0, y0, (1 - ax) * (1 - ay)), (x0 + 1, y0, ax * (1 - ay)),
               (x0, y0 + 1, (1 - ax) * ay), (x0 + 1, y0 + 1, ax * ay)]
    used = [(x, y, wt) for x, y, wt in corners
            if 0 <= x < w and 0 <= y < h and inside[y, x] and wt > 0]
    total = sum(wt for _, _, wt in used)
    if total <= 1e-9:
        return None
    qq = sum(wt * q[y, x] for x, y, wt in used) / total
    rr = sum(wt * r[y, x] for x, y, wt in used)
    return qq, rr / np.linalg.norm(rr)


def grid_sample_slope(inside, q, r, sx, sy, step=1e-6):
    """Twin of virtual.refine._sample_slope: grid_sample's Q and R at (sx, sy) and their
    derivatives along screen x and y, by forward differences of grid_sample over `step`
    pixels (the bilinear blend is smooth within a cell, so the step stays in it unless
    (sx, sy) lies within `step` of a cell's right or lower edge). None where grid_sample
    gives none. Returns (Q, dQ/dx, dQ/dy, R, dR/dx, dR/dy)."""
    at = grid_sample(inside, q, r, sx, sy)
    if at is None:
        return None
    along_x = grid_sample(inside, q, r, sx + step, sy)
    along_y = grid_sample(inside, q, r, sx, sy + step)
    return (at[0], (along_x[0] - at[0]) / step, (along_y[0] - at[0]) / step,
            at[1], (along_x[1] - at[1]) / step, (along_y[1] - at[1]) / step)


def refine_walk(p, seed, inside, q, r, iterations=20):
    """Twin of virtual.refine._walk: Gauss-Newton on c(s) = unit(P - Q(s)) - R(s) from
    `seed`, the Jacobian J by forward differences of c within the cell (step 1e-7 pixel),
    the step solving the normal equations (J^T J) step = -J^T c, or where J^T J is all but
    singular (det <= 1e-12 trace^2: the part's corners in one row or column) the least-norm
    step -J^T c / trace; capped at 8 pixels. Returns (status, Q at the end):
    EXACT (1) where a step under 1e-3 pixel is left and |c| <= 0.01 (Q at that step's end,
    on the linear model), BOUNDARY (2) where the walk leaves the part (Q extrapolated on the
    last point's linear model), NONE (0) if the part was never sampled."""
    h, w = inside.shape
    s = np.asarray(seed, np.float64).copy()
    status, end, rr = 0, None, None

    def residual(x, y):
        got = grid_sample(inside, q, r, x, y)
        if got is None or np.linalg.norm(p - got[0]) == 0.0:
            return None
        return (p - got[0]) / np.linalg.norm(p - got[0]) - got[1], got[0], got[1]

    for _ in range(iterations):
        if not (0.0 <= s[0] < w and 0.0 <= s[1] < h):
            break
        at = residual(*s)
        if at is None:
            break
        c, qq, rr = at
        status, end = 2, qq
        x0, y0 = math.floor(s[0] - 0.5), math.floor(s[1] - 0.5)
        if sum(0 <= x < w and 0 <= y < h and inside[y, x]
               for x in (x0, x0 + 1) for y in (y0, y0 + 1)) == 1:
            break  # a lone corner of the part: Q and R constant, no direction to go
        h_ = 1e-7
        cx, qx, _ = residual(s[0] + h_, s[1])
        cy, qy, _ = residual(s[0], s[1] + h_)
        jac = np.stack([(cx - c) / h_, (cy - c) / h_], 1)
        normal, gradient = jac.T @ jac, jac.T @ c
        trace = np.trace(normal)
        if np.linalg.det(normal) > 1e-12 * trace**2:
            step = np.linalg.solve(normal, -gradient)
        elif trace > 1e-30:  # rank one: the least-norm step
            step = -gradient / trace
        else:
            break
        if np.linalg.norm(step) > 8.0:
            step *= 8.0 / np.linalg.norm(step)
        end = qq + (qx - qq) / h_ * step[0] + (qy - qq) / h_ * step[1]
        if np.linalg.norm(step) < 1e-3:
            if c @ c <= 1e-4:
                status = 1
            break
        s += step
    if status == 1 and (p - end) @ rr <= 0.0:
        status = 2
    return status, end


def refine_point(p, seed, inside, q, r, eye):
    """Twin of virtual.refine._refine / _walk's answer for a point whose reflection lies
    on the part: the screen point s near `seed` where unit(P - Q(s)) = R(s) (Q, R from
    grid_sample), by scipy's least squares, and P' = E + unit(Q - E) (|Q - E| + |P - Q|).
    None where no zero residual is found."""
    from scipy.optimize import least_squares

    def residual(s):
        got = grid_sample(inside, q, r, s[0], s[1])
        if got is None:
            return np.full(3, 10.0)
        qq, rr = got
        return (p - qq) / np.linalg.norm(p - qq) - rr

    sol = least_squares(residual, np.asarray(seed, np.float64), diff_step=1e-6, xtol=1e-12,
                        ftol=1e-14, gtol=1e-14)
    if np.linalg.norm(sol.fun) > 1e-6:
        return None
    qq, _ = grid_sample(inside, q, r, *sol.x)
    e = qq - eye
    return eye + e / np.linalg.norm(e) * (np.linalg.norm(e) + np.linalg.norm(p - qq))


def tile_bounds(inside, q, r, size):
    """Twin of virtual.tiles._tile_bounds: per tile of `size` pixels holding part pixels
    (in tile-id order), over its part pixels grown by the row above and the column left:
    (center, radius) of Q, (unit axis, half-angle) of R, and the seed pixel (its own pixel
    whose Q is nearest the center, + 0.5)."""
    h, w = inside.shape
    ys, xs = np.nonzero(inside)
    out = []
    for t in np.unique((ys // size) * (w // size + 1) + xs // size):
        ty, tx = divmod(int(t), w // size + 1)
        y0, x0 = ty * size, tx * size
        ey, ex = max(y0 - 1, 0), max(x0 - 1, 0)
        by, bx = np.nonzero(inside[ey:y0 + size, ex:x0 + size])
        pts, dirs = q[by + ey, bx + ex], r[by + ey, bx + ex]
        c = pts.mean(axis=0)
        a = dirs.sum(axis=0)
        a /= max(float(np.linalg.norm(a)), 1e-30)
        dist = np.linalg.norm(pts - c, axis=1)
        own = (by + ey >= y0) & (bx + ex >= x0)
        mid = np.flatnonzero(own)[np.argmin(dist[own])]
        out.append((c, dist.max(), a, np.arccos(np.clip(dirs @ a, -1.0, 1.0)).max(),
                    (bx[mid] + ex + 0.5, by[mid] + ey + 0.5)))
    return [np.array([o[i] for o in out], np.float64) for i in range(5)]


def part_candidates(points, center, radius, axis, half):
    """Twin of virtual.tiles._candidates (PartTiles.candidates): points outside the ball
    (center, radius) and outside the cone about `axis` of half-angle `half` grown by the
    ball's spread asin(radius / dist) (angles by arccos, 1e-9 to spare) are not candidates."""
    out = np.zeros(len(points), bool)
    for k, p in enumerate(np.asarray(points, np.float64)):
        v = p - center
        dist = float(np.linalg.norm(v))
        if dist <= radius:
            out[k] = True
            continue
        spread = math.asin(radius / dist)
        angle = math.acos(float(np.clip(v @ axis / dist, -1.0, 1.0)))
        out[k] = half + spread >= math.pi or angle <= half + spread + 1e-9
    return out


def rows_of(marks, block):
    """Twin of virtual.tiles.rows_of: each part's marked points by np.flatnonzero, joined;
    where each part's rows and blocks of `block` rows start."""
    per = [np.flatnonzero(m) for m in marks]
    row_start = np.concatenate([[0], np.cumsum([len(x) for x in per])])
    block_start = np.concatenate([[0], np.cumsum([-(-len(x) // block) for x in per])])
    return np.concatenate(per), row_start, block_start


def joined(flag, polygons):
    """Twin of virtual.tiles._join (tiles.joined): the flagged points and every point of a
    polygon holding a flagged one."""
    out = np.array(flag, bool)
    for poly in polygons:
        if any(flag[i] for i in poly):
            out[list(poly)] = True
    return out


def scan(points, center, radius, axis, half, pixel, margin, q, r):
    """Twin of virtual.tiles._scan: a point is reached by tile j if it lies in the tile's
    ball (1.001 of the radius) or within half + margin + asin(radius / dist) of the axis
    (angles, by arccos); the seed is the middle pixel of the reaching tile whose ray passes
    closest (|unit(P - Q) - R|^2 at that pixel; first on ties), else of any tile."""
    n = points.shape[0]
    reach = np.zeros(n, bool)
    seeds = np.full((n, 2), np.nan)
    for k in range(n):
        p = points[k]
        errs, reached = [], []
        for j in range(center.shape[0]):
            x, y = int(pixel[j, 0]), int(pixel[j, 1])
            to_p = p - q[y, x]
            errs.append(float(np.sum((to_p / max(np.linalg.norm(to_p), 1e-30) - r[y, x]) ** 2)))
            v = p - center[j]
            dist = np.linalg.norm(v)
            if dist <= radius[j] * 1.001 or radius[j] / dist >= 1.0:
                reached.append(True)
                continue
            angle = math.acos(np.clip(v @ axis[j] / dist, -1.0, 1.0))
            reached.append(angle <= min(half[j] + margin + math.asin(radius[j] / dist),
                                        math.pi))
        errs = np.array(errs)
        if not len(errs):
            continue
        cand = np.flatnonzero(reached)
        j = cand[np.argmin(errs[cand])] if cand.size else int(np.argmin(errs))
        reach[k] = cand.size > 0
        seeds[k] = pixel[j]
    return reach, seeds


def map_coords(frame, res, s, d):
    """Twin of virtual.explosion.map_coords: T = s (x, y) / (2 sqrt(2 (z + 1))) + res / 2 of
    the unit direction d in the map frame (rows x, y, z)."""
    x, y, z = np.asarray(frame, np.float64) @ (np.asarray(d, np.float64) / np.linalg.norm(d))
    m = 2.0 * math.sqrt(max(2.0 * (z + 1.0), 1e-24))
    return s * x / m + res / 2.0, s * y / m + res / 2.0


def vertex_coords(v, n, used, eye, center, radius, frame, res, s):
    """Twin of virtual.explosion._vertex_coords: per used vertex, the eye ray reflected about
    its normal, followed from the vertex to the sphere (center, radius) it starts inside (the
    larger root of the quadratic), and the map coordinates of the hit's direction from the
    center; NaN for unused vertices."""
    coords = np.full((len(v), 2), np.nan)
    for i in range(len(v)):
        if not used[i]:
            continue
        d = (v[i] - eye) / np.linalg.norm(v[i] - eye)
        r = d - 2 * (d @ n[i]) * n[i]
        o = v[i] - center
        # |o + t r|^2 = radius^2 with |r| = 1: t^2 + 2 (o.r) t + |o|^2 - radius^2 = 0
        b, c = o @ r, o @ o - radius**2
        t = -b + math.sqrt(max(b * b - c, 0.0))
        coords[i] = map_coords(frame, res, s, o + t * r)
    return coords


def fill_triangle(ids, a, b, c, value, only_empty):
    """Twin of virtual.mapfill._fill_triangle: every texel whose center has non-negative
    barycentrics in (a, b, c) gets `value` (only empty ones if `only_empty`), over the whole
    map at once; degenerate or NaN triangles fill nothing."""
    (ax, ay), (bx, by), (cx, cy) = a, b, c
    area = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
    if area == 0.0 or math.isnan(area):
        return
    res = ids.shape[0]
    py, px = np.mgrid[0:res, 0:res] + 0.5
    w0 = ((bx - px) * (cy - py) - (cx - px) * (by - py)) / area
    w1 = ((cx - px) * (ay - py) - (ax - px) * (cy - py)) / area
    w2 = 1.0 - w0 - w1
    inside = (w0 >= 0) & (w1 >= 0) & (w2 >= 0)
    if only_empty:
        inside &= ids < 0
    ids[inside] = value


def nearest_filled_distance(empty):
    """Twin of virtual.mapfill._nearest_filled, by brute force: per texel, the Euclidean
    distance (texel centers) to the nearest texel that is not empty."""
    h, w = empty.shape
    fy, fx = np.nonzero(~empty)
    yy, xx = np.mgrid[0:h, 0:w]
    d2 = (yy[..., None] - fy) ** 2 + (xx[..., None] - fx) ** 2
    return np.sqrt(d2.min(axis=-1))


def nearest_filled_texel(layer, y, x):
    """Twin of virtual.mapfill._fill_holes' nearest filled texels, by brute force over the
    whole map: the filled (>= 0) texel nearest to (y, x), ties to the least column and
    then the least row (the rule _nearest_filled's two passes follow); None if none."""
    fy, fx = np.nonzero(layer >= 0)
    if not len(fy):
        return None
    d2 = (fy - y) ** 2 + (fx - x) ** 2
    keys = sorted(zip(d2, fx, fy, strict=True))
    return int(keys[0][2]), int(keys[0][1])


def fill_faces(ids, coords, faces, drawn):
    """Twin of virtual.mapfill._fill_faces: the drawn faces in order, filled with their id."""
    for fi in drawn:
        fill_triangle(ids, *(coords[faces[fi, k]] for k in range(3)), fi, False)


def fill_extensions(ids, coords, extensions, n_faces, center, reach):
    """Twin of virtual.mapfill._fill_extensions / _extend: each extension's quad, from its
    edge (i, j) out to `reach` from the map center along the directions of its ends, filled
    where empty with n_faces + its index (as two triangles; fill_triangle takes either
    winding)."""
    def out(p):
        d = np.asarray(p, np.float64) - center
        length = np.linalg.norm(d)
        return p if length == 0 else center + d * reach / length

    for e, (_, i, j) in enumerate(extensions):
        a, b = coords[i], coords[j]
        c, d = out(b), out(a)
        for tri in ((a, b, c), (a, c, d)):
            fill_triangle(ids, *tri, n_faces + e, True)


def plane_from_map(ids, coords, v, n, faces, extensions, t):
    """Twin of virtual.explosion._plane_from_map: the texel under T; a face: its vertices
    and normals weighted by T's barycentrics among its map corners (a third each if the
    corners are degenerate); an extension: by T's position along its inner edge, clamped.
    Returns (point, unit normal), the normal zero for an empty texel."""
    res = ids.shape[0]
    x = min(max(math.floor(t[0]), 0), res - 1)
    y = min(max(math.floor(t[1]), 0), res - 1)
    ident = ids[y, x]
    if ident < 0:
        return np.zeros(3), np.zeros(3)
    if ident < len(faces):
        idx = faces[ident]
        a, b, c = (coords[i] for i in idx)
        m = np.array([b - a, c - a]).T
        if np.linalg.det(m) == 0:
            wts = np.full(3, 1.0 / 3.0)
        else:
            wb, wc = np.linalg.solve(m, np.asarray(t, np.float64) - a)
            wts = np.array([1.0 - wb - wc, wb, wc])
        p, nn = wts @ v[idx], wts @ n[idx]
    else:
        i, j = extensions[ident - len(faces), 1:]
        edge = coords[j] - coords[i]
        ll = edge @ edge
        u = 0.5 if ll == 0 else float(np.clip((np.asarray(t) - coords[i]) @ edge / ll, 0, 1))
        p, nn = (1 - u) * v[i] + u * v[j], (1 - u) * n[i] + u * n[j]
    length = np.linalg.norm(nn)
    return p, (nn / length if length > 0 else nn)


def screen_plane(faces, f, screen, v, n, s):
    """Twin of virtual.explosion._screen_plane: point and unit normal of reflector face f at
    screen point s, by s's barycentrics among the face's screen corners (numpy's solver);
    a zero normal for a degenerate face."""
    idx = faces[f]
    a, b, c = (screen[i] for i in idx)
    m = np.array([b - a, c - a]).T
    if np.linalg.det(m) == 0:
        return np.zeros(3), np.zeros(3)
    wb, wc = np.linalg.solve(m, np.asarray(s, np.float64) - a)
    wts = np.array([1.0 - wb - wc, wb, wc])
    nn = wts @ n[idx]
    return wts @ v[idx], nn / np.linalg.norm(nn)


def explosion_virtual(points, v, n, faces, extensions, ids, coords, radii, center, flip_axis,
                      frame, res, s, hidden_face, hidden_screen, screen, cores):
    """Twin of virtual.explosion._virtual / _mirror: per point, a hidden one is mirrored
    across the plane screen_plane gives at its screen position; the others look up the
    direction from the center (turned around when it points against flip_axis) in the two
    layers whose spheres bracket their distance (the last pair beyond), mirror across both
    layers' planes and blend by inverse distance to each sphere (a layer whose texel is empty
    weighs 0; none: Q' = Q). unreflected: the texel is not core in both layers."""
    out = np.empty((len(points), 3))
    unreflected = np.zeros(len(points), bool)
    for i, q in enumerate(points):
        h = hidden_face[i]
        if h >= 0:
            p, nn = screen_plane(faces, h, screen, v, n, hidden_screen[i])
            if np.any(nn != 0):
                out[i] = _reflect_across(q, p, nn)
                continue
        d = q - center
        if d @ flip_axis < 0:
            d = -d
        t = map_coords(frame, res, s, d)
        dist = np.linalg.norm(q - center)
        lo = 0
        while lo < len(radii) - 2 and dist > radii[lo + 1]:
            lo += 1
        cx = min(max(math.floor(t[0]), 0), res - 1)
        cy = min(max(math.floor(t[1]), 0), res - 1)
        unreflected[i] = not (cores[lo, cy, cx] and cores[lo + 1, cy, cx])
        total, acc = 0.0, np.zeros(3)
        for layer in (lo, lo + 1):
            p, nn = plane_from_map(ids[layer], coords[layer], v, n, faces, extensions, t)
            if not np.any(nn != 0):
                continue
            wt = 1.0 / max(abs(dist - radii[layer]), 1e-12)
            total += wt
            acc += wt * _reflect_across(q, p, nn)
        out[i] = acc / total if total > 0 else q
    return out, unreflected


# --- distance cube maps (maps/distance_search.py), written from that module's docstring with
# plain numpy vectors and an independent cube-face projection

AXES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
UPS = np.array([[0, 1, 0], [0, 1, 0], [0, 0, 1], [0, 0, -1], [0, 1, 0], [0, 1, 0]], float)


def face_uv(u):
    """(face, s, t): the face of u's major axis; s, t in [0, 1] (row 0 at the top)."""
    u = np.asarray(u, float)
    i = int(np.argmax(np.abs(u)))
    # ties resolve x before y before z, as the kernel does
    a = np.abs(u)
    if a[0] >= a[1] and a[0] >= a[2]:
        i = 0
    elif a[1] >= a[2]:
        i = 1
    else:
        i = 2
    face = 2 * i + (0 if u[i] > 0 else 1)
    axis = AXES[face]
    right = np.cross(UPS[face], -axis)
    right /= np.linalg.norm(right)
    up = np.cross(-axis, right)
    fwd = u @ axis
    return face, ((u @ right) / fwd + 1) / 2, (1 - (u @ up) / fwd) / 2


def layer_sample(q, surface, k, u):
    """Twin of maps.distance_search.sample_layer: (face, s, t, id, 1/w) of direction u in
    layer k, by the module's rule."""
    face, s, t = face_uv(u)
    res = q.shape[2]
    fx, fy = s * res, t * res
    xn, yn = min(max(int(fx), 0), res - 1), min(max(int(fy), 0), res - 1)
    sid = int(surface[k, face, yn, xn])
    if sid < 0:
        return face, s, t, sid, 0.0
    x0 = min(max(math.floor(fx - 0.5), 0), res - 2)
    y0 = min(max(math.floor(fy - 0.5), 0), res - 2)
    block = surface[k, face, y0:y0 + 2, x0:x0 + 2]
    if np.all(block == sid):
        ax, ay = fx - 0.5 - x0, fy - 0.5 - y0
        w = np.array([[(1 - ax) * (1 - ay), ax * (1 - ay)], [(1 - ax) * ay, ax * ay]])
        return face, s, t, sid, float((w * q[k, face, y0:y0 + 2, x0:x0 + 2]).sum())
    return face, s, t, sid, float(q[k, face, yn, xn])


def bilinear(image, s, t):
    res = image.shape[0]
    fx = min(max(s * res - 0.5, 0.0), res - 1.0)
    fy = min(max(t * res - 0.5, 0.0), res - 1.0)
    x0, y0 = min(int(fx), res - 2), min(int(fy), res - 2)
    ax, ay = fx - x0, fy - y0
    return ((1 - ax) * (1 - ay) * image[y0, x0] + ax * (1 - ay) * image[y0, x0 + 1]
            + (1 - ax) * ay * image[y0 + 1, x0] + ax * ay * image[y0 + 1, x0 + 1])


def naive_search(x, r, a, t_end, q, surface, color, steps, refine):
    """Twin of maps.distance_search.search_ray (and _search_pixels per pixel): (hit, colour)
    of the ray x + r d in a layered map, by the module docstring's rule."""
    x, r = np.asarray(x, float), np.asarray(r, float)
    layers = q.shape[0]

    def u_at(t):
        return (1 - t) * x + t * a * r

    def look(t):
        u = u_at(t)
        rows = []
        for k in range(layers):
            face, _, _, sid, qv = layer_sample(q, surface, k, u)
            g = (u @ AXES[face]) * qv - (1 - t)
            dist = np.linalg.norm(u) / ((u @ AXES[face]) * qv) if qv > 0 else np.inf
            rows.append((sid, g, dist))
        return rows

    def angle(u, v):
        return math.acos(min(max(u @ v / (np.linalg.norm(u) * np.linalg.norm(v)), -1), 1))

    prev_t, prev = 0.0, look(0.0)
    for i in range(1, steps + 1):
        t = t_end * i / steps
        now = look(t)
        if now[0][0] < 0:
            continue
        step_angle = angle(u_at(prev_t), u_at(t))
        found = []
        for sid, g, dist in now:
            if sid < 0 or g < 0:
                continue
            partner = next((p for p in prev if p[0] == sid and p[1] < 0), None)
            if partner is None:
                partner = next((p for p in prev if p[0] >= 0 and p[1] < 0 and abs(p[2] - dist)
                                <= CREASE_SLOPE * step_angle * max(p[2], dist)), None)
            if partner is not None:
                tc = prev_t + (t - prev_t) * partner[1] / (partner[1] - g)
                found.append((tc, partner[0], sid, partner[1], g))
        if found:
            _, sid_a, sid_b, g_lo, g_hi = min(found, key=lambda f: f[0])

            def on_surface(tt, sid_a=sid_a, sid_b=sid_b):
                for k, (sid, g, _) in enumerate(look(tt)):
                    if sid >= 0 and sid in (sid_a, sid_b):
                        return g, k
                return 0.0, -1

            lo, hi, t_hit = prev_t, t, t
            for _ in range(refine):
                tc = lo + (hi - lo) * g_lo / (g_lo - g_hi)
                g, k = on_surface(tc)
                if k < 0:
                    break
                t_hit = tc
                if g < 0:
                    lo, g_lo = tc, g
                elif g > 0:
                    hi, g_hi = tc, g
                else:
                    break
            _, k = on_surface(t_hit)
            face, s, tt = face_uv(u_at(t_hit))
            return True, bilinear(color[max(k, 0), face], s, tt)
        prev_t, prev = t, now
    return False, None


def reflected_ray(tri, b1, b2, corners, normals, kind, p, eye):
    """Twin of reflection.reflected_ray: the point at barycentrics (b1, b2) of
    triangle `tri` and the law of reflection r = 2 (n.v) n - v about its normal (the plane's,
    the sphere's radial, the cylinder's radial across its axis, or the mesh's interpolated
    one), turned toward the eye."""
    c = np.asarray(corners[tri], float)
    w = np.array([1.0 - b1 - b2, b1, b2])
    point = w @ c
    if kind == PLANAR:
        n = np.asarray(p[:3], float)
    elif kind == SPHERE:
        n = point - np.asarray(p[:3], float)
    elif kind == CYLINDER:
        axis = np.asarray(p[3:6], float)
        radial = point - np.asarray(p[:3], float)
        n = radial - (radial @ axis) * axis
    else:
        n = w @ np.asarray(normals[tri], float)
    n = n / np.linalg.norm(n)
    v = np.asarray(eye, float) - point
    v = v / np.linalg.norm(v)
    if n @ v < 0:
        n = -n
    return point, 2.0 * (n @ v) * n - v


# --- dprm's colour gather and fill (maps/warp/)


def gather_rows(best_id, stride, per_map, box, out):
    """Twin of maps.warp.gather_colors (and its _gather4): out[y, x] = per_map[id // stride]
    [id % stride] where a zexel reached pixel (x, y) of box (x0, x1, y0, y1)."""
    out = out.copy()
    x0, x1, y0, y1 = box
    for y in range(y0, y1):
        for x in range(x0, x1):
            ident = int(best_id[y, x])
            if ident >= 0:
                out[y, x] = per_map[ident // stride][ident % stride]
    return out


def fill_and_blend(stencil, best_id, reflected, prev_rgb, prev_filled, background,
                   reflectance, rgb):
    """Twin of maps.warp.fill_blend, in numpy masks: the warped colour where a zexel landed,
    else the previous frame's where that was filled (prev_rgb None: no previous frame), else
    the background, a hole; rgb += reflectance * that over the stencil. Returns (rgb,
    holes, reflected, filled)."""
    reached = stencil & (best_id >= 0)
    reflected = reflected.copy()
    filled = reached.copy()
    if prev_rgb is not None:
        reuse = stencil & ~reached & prev_filled
        reflected[reuse] = prev_rgb[reuse]
        filled |= reuse
    hole = stencil & ~filled
    reflected[hole] = background
    rgb = rgb.copy()
    rgb[stencil] += np.asarray(reflectance) * reflected[stencil]
    return rgb, hole.astype(np.float32), reflected, filled


def weld_within(points, tolerance=1e-9):
    """Twin of scene.teapot.weld_points: every cluster of points closer than `tolerance`
    (a KD-tree's pairs, joined transitively) replaced by its first member."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    flat = points.reshape(-1, 3)
    pairs = cKDTree(flat).query_pairs(tolerance, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])),
                       shape=(len(flat), len(flat)))
    _, label = connected_components(graph, directed=False)
    first = np.full(label.max() + 1, len(flat))
    np.minimum.at(first, label, np.arange(len(flat)))
    return flat[first[label]].reshape(points.shape)


def part_labels(triangle, surface, sid, first, label_of, depth):
    """Twin of virtual.partpasses.part_labels over the whole image: (labels uint8, stencil
    bool, floor float32, boxes (L, 4) y0, y1, x0, x1 of each label's pixels, zeros for a
    label with none)."""
    count = len(label_of) - 1
    face = triangle.astype(np.int64) - first
    face = np.where((face >= 0) & (face < count), face, count)
    labels = np.where(surface == sid, label_of[face], 0).astype(np.uint8)
    stencil = labels != 0
    boxes = np.zeros((int(label_of.max()), 4), np.int64)
    for b in range(len(boxes)):
        ys, xs = np.nonzero(labels == b + 1)
        if ys.size:
            boxes[b] = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    return labels, stencil, np.where(stencil, depth, 0.0).astype(np.float32), boxes


def pass_labels(surface, depth, n_objects, label_of):
    """Twin of virtual.compose.pass_labels over the whole image (the box is an
    optimisation): (labels uint8, stencil bool, floor float32)."""
    k = surface.astype(np.int64) - n_objects
    mirror = (k >= 0) & (k < len(label_of))
    labels = np.where(mirror, label_of[np.clip(k, 0, len(label_of) - 1)], 0).astype(np.uint8)
    stencil = labels != 0
    return labels, stencil, np.where(stencil, depth, 0.0).astype(np.float32)


def compose_passes(rgb, colors, triangle, labels, reflectance):
    """Twin of virtual.compose.compose_passes (the whole image): per label p + 1, the
    twins of fill_cracks (covered: that label's pixels with a triangle) and add_reflection
    with reflectance[p], one label at a time. Returns the new rgb; fills `colors`."""
    out = rgb.copy()
    for p in range(len(reflectance)):
        stencil = labels == p + 1
        fill_cracks(colors, stencil & (triangle >= 0), stencil)
        out = add_reflection(out, colors, stencil, reflectance[p])
    return out


def ray_focus(vertices, normals, eye):
    """virtual.explosion.ray_focus (its sums: explosion._focus_sums) as whole-array numpy,
    its code before session 16: the least-squares point nearest the front-facing vertices'
    reflection rays, or the vertex mean."""
    v, n = vertices, normals
    d = v - eye
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    front = np.einsum("ij,ij->i", n, -d) >= 0.0
    if front.sum() < 3:
        return v.mean(axis=0)
    v, n, d = v[front], n[front], d[front]
    r = d - 2.0 * np.einsum("ij,ij->i", d, n)[:, None] * n
    proj = np.eye(3)[None] - r[:, :, None] * r[:, None, :]  # (I - r r^T) per ray
    a = proj.sum(axis=0)
    b = np.einsum("kij,kj->i", proj, v)
    if np.linalg.cond(a) > 1e8:
        return vertices.mean(axis=0)
    return np.linalg.solve(a, b)


def setup_arrays(v, n, f, boundary, eye):
    """virtual.explosion._setup_arrays (map_setup's arrays) as whole-array numpy, its code
    before session 16: (fixed normals, front, used, drawn face indices, extensions)."""
    to_eye = eye - v
    front = np.einsum("ij,ij->i", n, to_eye) >= 0.0
    face_front = front[f]
    profile = face_front.any(axis=1) & ~face_front.all(axis=1)
    fixed = n.copy()
    needs = np.zeros(len(v), bool)
    needs[f[profile].reshape(-1)] = True
    needs &= ~front
    sight = -to_eye / np.linalg.norm(to_eye, axis=1, keepdims=True)
    proj = fixed[needs] - np.einsum("ij,ij->i", fixed[needs], sight[needs])[:, None] * sight[needs]
    fixed[needs] = proj / np.maximum(np.linalg.norm(proj, axis=1, keepdims=True), 1e-30)
    used = front | needs
    drawn = face_front.all(axis=1) | profile
    two_back = profile & (face_front.sum(axis=1) == 1)
    back_faces = np.flatnonzero(two_back)
    back = f[back_faces][~face_front[back_faces]].reshape(-1, 2)
    ext = np.column_stack([back_faces, back]).astype(np.int64)
    open_edges = boundary[drawn[boundary[:, 0]] & used[boundary[:, 1]] & used[boundary[:, 2]]]
    return fixed, front, used, np.flatnonzero(drawn), np.concatenate([ext.reshape(-1, 3),
                                                                     open_edges])


def screen_from_world(points, clip_from_world, width, height):
    """virtual.screen.screen_from_world (its kernel: _screen_rows) as whole-array numpy,
    its code before session 17: clip coordinates by `@`, divided, mapped to pixels."""
    from reflectcli.camera import screen_from_ndc

    h = points @ clip_from_world[:3, :3].T + clip_from_world[:3, 3]
    w = points @ clip_from_world[3, :3] + clip_from_world[3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        x, y = screen_from_ndc(h[:, 0] / w, h[:, 1] / w, width, height)
    return np.stack([x, y, w], axis=1)


def part_extent(vertices, normals, centre, scene_points, eye):
    """virtual.part._extent as whole-array numpy, its code before session 17: (bound, far,
    front)."""
    bound = float(np.linalg.norm(vertices - centre, axis=1).max())
    far = float(np.linalg.norm(scene_points - centre, axis=1).max())
    front = np.einsum("ij,ij->i", normals, eye - vertices) >= 0.0
    return bound, far, front


def fused_multiply_add(a, b, c):
    """reflectcli.fused.fma, exactly: a * b + c in rationals, rounded once to float64."""
    from fractions import Fraction

    return float(Fraction(float(a)) * Fraction(float(b)) + Fraction(float(c)))


def part_ball(center, radius, axis, half):
    """virtual.tiles._balls for one part as whole-array numpy, its code before session 17
    (PartTiles._set): (ball center, ball radius, cone axis, cone half-angle) holding the
    tiles' balls (center, radius) and cones (axis, half)."""
    n = radius.size
    part_center = center.mean(axis=0) if n else np.zeros(3)
    part_radius = (float(np.max(np.linalg.norm(center - part_center, axis=1)
                                + radius * 1.001)) * (1 + 1e-9) if n else 0.0)
    a = axis.sum(axis=0) if n else np.zeros(3)
    norm = float(np.linalg.norm(a))
    part_axis = a / norm if norm > 0 else np.array([0.0, 0.0, 1.0])
    part_half = (float(np.max(np.arccos(np.clip(axis @ part_axis, -1, 1)) + half)) + 1e-9
                 if n and norm > 0 else math.pi)
    return part_center, part_radius, part_axis, part_half

def map_frame(center, eye):
    """virtual.explosion.map_frame (its kernel _map_frames) as whole-vector numpy, its code
    before session 22: rows x, y, z of the map's axes."""
    def cross(a, b):
        return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                         a[0] * b[1] - a[1] * b[0]])

    z = eye - center
    z = z / np.linalg.norm(z)
    helper = np.array([0.0, 1.0, 0.0]) if abs(z[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = cross(helper, z)
    x /= np.linalg.norm(x)
    return np.array([x, cross(z, x), z])


def lookup_axis(normals, front):
    """virtual.part._lookup_axis as numpy, its code before session 22: the front vertices'
    mean normal made unit (0 with no front vertex)."""
    if not front.any():
        return np.zeros(3)
    flip = normals[front].mean(axis=0)
    return flip / max(np.linalg.norm(flip), 1e-30)
