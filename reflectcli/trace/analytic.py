"""Exact ray intersection with planar, sphere and open-cylinder mirrors (world space, numba).

Planar mirrors are intersected here rather than by Embree: two triangles per mirror do not
pay for Embree's per-ray call overhead, and float64 keeps flush mirrors exact.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..scene.types import (
    CYLINDER,
    CYLINDER_AXIS,
    CYLINDER_HEIGHT,
    CYLINDER_ORIGIN,
    CYLINDER_RADIUS,
    PLANAR,
    PLANE_D,
    PLANE_NORMAL,
    PLANE_P00,
    PLANE_P01,
    PLANE_P10,
    PLANE_P11,
    SPHERE,
    SPHERE_CENTER,
    SPHERE_RADIUS,
)


def intersect_analytic(
    origins: np.ndarray, directions: np.ndarray, tfar: np.ndarray, kind: np.ndarray,
    params: np.ndarray, tmin: float, out: tuple[np.ndarray, np.ndarray] | None = None,
    edges: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Nearest analytic-mirror hit per ray in (tmin, tfar): (t or inf, mirror index or -1).
    `out`: (n,) float32 and int32 arrays to fill instead of new ones; `edges`: the mirrors'
    quad_edges, when the caller keeps them (they are made here otherwise)."""
    n = origins.shape[0]
    if out is None:
        t = np.full(n, np.inf, np.float32)
        idx = np.full(n, -1, np.int32)
    else:
        t, idx = out
    if has_analytic(kind):
        params = np.ascontiguousarray(params, dtype=np.float64)
        # contiguous: the kernels read the rays through flat views
        origins, directions = np.ascontiguousarray(origins), np.ascontiguousarray(directions)
        if edges is None:
            edges = quad_edges(kind, params)
        _intersect(origins, directions, tfar, kind, params, edges, tmin, t, idx)
    elif out is not None:
        t.fill(np.inf)
        idx.fill(-1)
    return t, idx


def has_analytic(kind: np.ndarray) -> bool:
    """Is any mirror one the analytic intersector traces (not a triangle mesh)?"""
    return bool(np.any((kind == SPHERE) | (kind == CYLINDER) | (kind == PLANAR)))


QUAD_TRIANGLES = ((PLANE_P00, PLANE_P10, PLANE_P11), (PLANE_P00, PLANE_P11, PLANE_P01))


def screen_boxes(kind: np.ndarray, params: np.ndarray, camera) -> np.ndarray:
    """(M, 4) int64 per mirror: pixels x0 .. x1 - 1, rows y0 .. y1 - 1 of `camera`'s image
    outside of which no primary ray can meet the mirror (`intersect_rows`). The box holds the
    projections of the corners of the mirror's world-space bounding box, grown by a small
    world margin and 2 pixels: every point of the mirror lies in front of the eye when all
    corners do, and then projects into their projections' hull (a primary ray's pixel is
    where its hit point projects; the margins cover rounding). With a corner not in front of
    the eye the box is the whole image; other kinds of mirror (meshes) get an empty box."""
    right, up, back = camera.basis()
    eye = np.asarray(camera.eye, np.float64)
    w, h = camera.width, camera.height
    tan_half = math.tan(math.radians(camera.fov_y) / 2.0)
    boxes = np.zeros((kind.shape[0], 4), np.int64)
    for k in range(kind.shape[0]):
        p = params[k]
        if kind[k] == PLANAR:
            pts = p[PLANE_P00:PLANE_P01 + 3].reshape(4, 3)
            lo, hi = pts.min(axis=0), pts.max(axis=0)
        elif kind[k] == SPHERE:
            c, r = p[SPHERE_CENTER:SPHERE_CENTER + 3], abs(p[SPHERE_RADIUS])
            lo, hi = c - r, c + r
        elif kind[k] == CYLINDER:
            o = p[CYLINDER_ORIGIN:CYLINDER_ORIGIN + 3]
            ends = np.stack([o, o + p[CYLINDER_HEIGHT] * p[CYLINDER_AXIS:CYLINDER_AXIS + 3]])
            r = abs(p[CYLINDER_RADIUS])
            lo, hi = ends.min(axis=0) - r, ends.max(axis=0) + r
        else:
            continue
        margin = 1e-4 * (1.0 + max(np.abs(lo).max(), np.abs(hi).max()))
        lo, hi = lo - margin, hi + margin
        corners = np.stack(np.meshgrid(*zip(lo, hi, strict=True), indexing="ij"), -1)
        v = corners.reshape(-1, 3) - eye
        depth = -(v @ back)
        if not np.all(depth > 1e-9 * (1.0 + np.abs(v).max())):
            boxes[k] = (0, w, 0, h)
            continue
        col = ((v @ right) / depth / (tan_half * camera.aspect) + 1.0) * 0.5 * w
        row = (1.0 - (v @ up) / depth / tan_half) * 0.5 * h
        x0, x1 = max(0, math.floor(col.min()) - 2), min(w, math.ceil(col.max()) + 3)
        y0, y1 = max(0, math.floor(row.min()) - 2), min(h, math.ceil(row.max()) + 3)
        if x0 < x1 and y0 < y1:
            boxes[k] = (x0, x1, y0, y1)
    return boxes


def quad_edges(kind: np.ndarray, params: np.ndarray) -> np.ndarray:
    """(M, 6, 4) float64: per planar mirror, the edges of its two triangles (p00 p10 p11,
    p00 p11 p01) as planes through the edge along the mirror normal: m = n x (c_j - c_i)
    and m . c_i, so that a point p of the mirror's plane lies on the inner side of edge
    i -> j where m . p - m . c_i >= 0 (n . ((c_j - c_i) x (p - c_i)), worked out once per
    mirror instead of per ray). Rows of other mirrors are zero."""
    edges = np.zeros((kind.shape[0], 6, 4))
    for k in np.flatnonzero(kind == PLANAR):
        p = params[k]
        n = p[PLANE_NORMAL:PLANE_NORMAL + 3]
        for t, tri in enumerate(QUAD_TRIANGLES):
            for e in range(3):
                ci = p[tri[e]:tri[e] + 3]
                cj = p[tri[(e + 1) % 3]:tri[(e + 1) % 3] + 3]
                m = np.cross(n, cj - ci)
                edges[k, 3 * t + e, :3] = m
                edges[k, 3 * t + e, 3] = m @ ci
    return edges


@njit(cache=True, inline="always")
def _sphere(ox, oy, oz, dx, dy, dz, cx, cy, cz, r, tmin):
    """Smallest root > tmin of |o + t d - c| = r, or inf (float64 throughout)."""
    lx, ly, lz = ox - cx, oy - cy, oz - cz
    a = dx * dx + dy * dy + dz * dz
    b = lx * dx + ly * dy + lz * dz
    c = lx * lx + ly * ly + lz * lz - r * r
    disc = b * b - a * c
    if disc < 0.0:
        return np.inf
    s = math.sqrt(disc)
    # numerically stable roots
    q = -(b + math.copysign(s, b))
    if q == 0.0:
        return np.inf
    t0 = q / a
    t1 = c / q
    if t0 > t1:
        t0, t1 = t1, t0
    if t0 > tmin:
        return t0
    if t1 > tmin:
        return t1
    return np.inf


@njit(cache=True, inline="always")
def _cylinder(ox, oy, oz, dx, dy, dz, params, k, tmin):
    """Smallest t > tmin on the open tube of mirror k (params row: origin, unit axis, radius,
    height; read in place: a row view per ray costs reference counting)."""
    p = params
    ax, ay, az = p[k, CYLINDER_AXIS], p[k, CYLINDER_AXIS + 1], p[k, CYLINDER_AXIS + 2]
    lx = ox - p[k, CYLINDER_ORIGIN]
    ly = oy - p[k, CYLINDER_ORIGIN + 1]
    lz = oz - p[k, CYLINDER_ORIGIN + 2]
    dd = dx * ax + dy * ay + dz * az
    ld = lx * ax + ly * ay + lz * az
    # components perpendicular to the axis
    ux, uy, uz = dx - dd * ax, dy - dd * ay, dz - dd * az
    wx, wy, wz = lx - ld * ax, ly - ld * ay, lz - ld * az
    a = ux * ux + uy * uy + uz * uz
    if a == 0.0:
        return np.inf
    b = ux * wx + uy * wy + uz * wz
    c = wx * wx + wy * wy + wz * wz - p[k, CYLINDER_RADIUS] * p[k, CYLINDER_RADIUS]
    disc = b * b - a * c
    if disc < 0.0:
        return np.inf
    s = math.sqrt(disc)
    for sign in (-1.0, 1.0):
        t = (-b + sign * s) / a
        if t > tmin:
            h = ld + t * dd
            if 0.0 <= h <= p[k, CYLINDER_HEIGHT]:
                return t
    return np.inf


@njit(cache=True, inline="always")
def _quad_run(lo, hi, base, o_flat, d_flat, params, edges, k, tmin, best, found):
    """Planar mirror k (triangles p00 p10 p11 and p00 p11 p01, edges inclusive; `edges`:
    quad_edges) against rays lo .. hi - 1 (origins and directions as flat float32 views, ray
    i at 3 * i): where the ray meets the quad at t > tmin and t < best[i - base], best
    becomes t and found[i] k. The loop has no branch and no exit, so it runs as vector code:
    the mirror's plane and edges are read into scalars first (a read of `edges` inside it
    could be the same memory as a write to `best`, for all the compiler knows), and the
    division is by 1 where the ray runs parallel to the plane (numba's check for a zero
    divisor would leave the loop). Lane by lane the same arithmetic as scalar code, so the
    same bits."""
    nx, ny, nz = params[k, PLANE_NORMAL], params[k, PLANE_NORMAL + 1], params[k, PLANE_NORMAL + 2]
    pd = params[k, PLANE_D]
    a0, a1, a2, a3 = edges[k, 0, 0], edges[k, 0, 1], edges[k, 0, 2], edges[k, 0, 3]
    b0, b1, b2, b3 = edges[k, 1, 0], edges[k, 1, 1], edges[k, 1, 2], edges[k, 1, 3]
    c0, c1, c2, c3 = edges[k, 2, 0], edges[k, 2, 1], edges[k, 2, 2], edges[k, 2, 3]
    d0, d1, d2, d3 = edges[k, 3, 0], edges[k, 3, 1], edges[k, 3, 2], edges[k, 3, 3]
    e0, e1, e2, e3 = edges[k, 4, 0], edges[k, 4, 1], edges[k, 4, 2], edges[k, 4, 3]
    f0, f1, f2, f3 = edges[k, 5, 0], edges[k, 5, 1], edges[k, 5, 2], edges[k, 5, 3]
    mirror = np.int32(k)
    f64 = np.float64
    three = np.uint64(3)
    for n in range(hi - lo):
        i = np.uint64(lo + n)  # unsigned, as in resolve.resolve_range
        r = np.uint64(lo + n - base)
        x, y, z = three * i, three * i + np.uint64(1), three * i + np.uint64(2)
        ox, oy, oz = f64(o_flat[x]), f64(o_flat[y]), f64(o_flat[z])
        dx, dy, dz = f64(d_flat[x]), f64(d_flat[y]), f64(d_flat[z])
        denom = nx * dx + ny * dy + nz * dz
        crosses = denom != 0.0
        t = -(nx * ox + ny * oy + nz * oz + pd) / (denom if crosses else 1.0)
        px, py, pz = ox + t * dx, oy + t * dy, oz + t * dz
        # inner side of (or on) each edge; NaN counts in
        first = (_inner(a0, a1, a2, a3, px, py, pz) & _inner(b0, b1, b2, b3, px, py, pz)
                 & _inner(c0, c1, c2, c3, px, py, pz))
        second = (_inner(d0, d1, d2, d3, px, py, pz) & _inner(e0, e1, e2, e3, px, py, pz)
                  & _inner(f0, f1, f2, f3, px, py, pz))
        nearer = crosses & (t > tmin) & (first | second) & (t < best[r])
        best[r] = t if nearer else best[r]
        found[i] = mirror if nearer else found[i]


@njit(cache=True, inline="always")
def _inner(mx, my, mz, w, px, py, pz):
    """Is the point on the inner side of (or on) the edge plane m . p = w (quad_edges; NaN
    counts in)?"""
    return not (mx * px + my * py + mz * pz - w < 0.0)


@njit(cache=True, inline="always")
def _mirror_run(lo, hi, base, origins, directions, o_flat, d_flat, kind, params, edges, k,
                tmin, best, found):
    """Mirror k against rays lo .. hi - 1: where a ray meets it at t > tmin nearer than
    best[i - base], best becomes t and found[i] k (planar mirrors as vector code,
    `_quad_run`)."""
    if kind[k] == PLANAR:
        _quad_run(lo, hi, base, o_flat, d_flat, params, edges, k, tmin, best, found)
        return
    if kind[k] != SPHERE and kind[k] != CYLINDER:
        return
    f64 = np.float64
    for n in range(hi - lo):
        i = np.uint64(lo + n)
        r = np.uint64(lo + n - base)
        ox, oy, oz = f64(origins[i, 0]), f64(origins[i, 1]), f64(origins[i, 2])
        dx, dy, dz = f64(directions[i, 0]), f64(directions[i, 1]), f64(directions[i, 2])
        if kind[k] == SPHERE:
            t = _sphere(ox, oy, oz, dx, dy, dz, params[k, SPHERE_CENTER],
                        params[k, SPHERE_CENTER + 1], params[k, SPHERE_CENTER + 2],
                        params[k, SPHERE_RADIUS], tmin)
        else:
            t = _cylinder(ox, oy, oz, dx, dy, dz, params, k, tmin)
        if t < best[r]:
            best[r] = t
            found[i] = k


@njit(cache=True, inline="always")
def _start(a, b, tfar, found):
    """The running nearest t (float64) of rays a .. b - 1, from their tfar (tfar[i], or
    tfar[0] for all when it has one entry), and no mirror found yet."""
    best = np.empty(b - a)
    one = tfar.shape[0] == 1
    for n in range(b - a):
        i = np.uint64(a + n)
        best[n] = np.float64(tfar[0] if one else tfar[i])
        found[i] = -1
    return best


@njit(cache=True, inline="always")
def _finish(a, b, best, t_out, found):
    """t_out[i] of rays a .. b - 1: the nearest t found (as float32), inf where none was."""
    for n in range(b - a):
        i = np.uint64(a + n)
        t_out[i] = best[n] if found[i] >= 0 else np.inf


@njit(cache=True, parallel=True)
def _intersect(origins, directions, tfar, kind, params, edges, tmin, t_out, idx_out):
    """intersect_range over all rays, in runs of 4096 shared among the threads."""
    n = origins.shape[0]
    for c in prange((n + 4095) // 4096):
        intersect_range(c * 4096, min(n, (c + 1) * 4096), origins, directions, tfar, kind,
                        params, edges, tmin, t_out, idx_out)


@njit(cache=True, inline="always")
def intersect_range(a, b, origins, directions, tfar, kind, params, edges, tmin, t_out,
                    idx_out):
    """intersect_analytic for rays a .. b - 1 (tfar[i], or tfar[0] for all when it has one
    entry), written at their indices: t or inf, mirror index or -1. Mirror by mirror over the
    rays, in the mirrors' order (the nearer wins, the first on a tie), each ray's running
    nearest t in float64."""
    best = _start(a, b, tfar, idx_out)
    o_flat, d_flat = origins.reshape(-1), directions.reshape(-1)
    for k in range(kind.shape[0]):
        _mirror_run(a, b, a, origins, directions, o_flat, d_flat, kind, params, edges, k, tmin,
                    best, idx_out)
    _finish(a, b, best, t_out, idx_out)


@njit(cache=True, inline="always")
def intersect_rows(a, b, j0, per_row, spp, boxes, origins, directions, tfar, kind, params,
                   edges, tmin, t_out, idx_out):
    """intersect_range for primary rays a .. b - 1, image rows j0 onward (per_row rays a
    row, spp a pixel): each mirror is traced only on the rays of pixels within its
    `screen_boxes` box; the others can meet none and get a miss."""
    best = _start(a, b, tfar, idx_out)
    o_flat, d_flat = origins.reshape(-1), directions.reshape(-1)
    j = j0
    for first in range(a, b, per_row):
        last = min(b, first + per_row)
        for k in range(boxes.shape[0]):
            if boxes[k, 2] <= j < boxes[k, 3]:
                lo = first + boxes[k, 0] * spp
                hi = min(last, first + boxes[k, 1] * spp)
                _mirror_run(lo, hi, a, origins, directions, o_flat, d_flat, kind, params,
                            edges, k, tmin, best, idx_out)
        j += 1
    _finish(a, b, best, t_out, idx_out)
