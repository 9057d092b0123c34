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
def _quad(ox, oy, oz, dx, dy, dz, params, edges, k, tmin):
    """t > tmin where the ray meets planar mirror k's quad (triangles p00 p10 p11 and p00 p11
    p01, edges inclusive; `edges`: quad_edges). Rows are read in place (a row view per ray
    costs reference counting)."""
    nx, ny, nz = params[k, PLANE_NORMAL], params[k, PLANE_NORMAL + 1], params[k, PLANE_NORMAL + 2]
    denom = nx * dx + ny * dy + nz * dz
    if denom == 0.0:
        return np.inf
    t = -(nx * ox + ny * oy + nz * oz + params[k, PLANE_D]) / denom
    if not t > tmin:
        return np.inf
    px, py, pz = ox + t * dx, oy + t * dy, oz + t * dz
    if (_inner(edges, k, 0, px, py, pz) and _inner(edges, k, 1, px, py, pz)
            and _inner(edges, k, 2, px, py, pz)):
        return t
    if (_inner(edges, k, 3, px, py, pz) and _inner(edges, k, 4, px, py, pz)
            and _inner(edges, k, 5, px, py, pz)):
        return t
    return np.inf


@njit(cache=True, inline="always")
def _inner(edges, k, e, px, py, pz):
    """Is the point on the inner side of (or on) edge e of mirror k's quad_edges (NaN counts
    in)?"""
    return not (edges[k, e, 0] * px + edges[k, e, 1] * py + edges[k, e, 2] * pz
                - edges[k, e, 3] < 0.0)


@njit(cache=True, parallel=True)
def _intersect(origins, directions, tfar, kind, params, edges, tmin, t_out, idx_out):
    for i in prange(origins.shape[0]):
        _nearest_into(i, origins, directions, tfar, kind, params, edges, tmin, t_out, idx_out)


@njit(cache=True, inline="always")
def intersect_range(a, b, origins, directions, tfar, kind, params, edges, tmin, t_out,
                    idx_out):
    """intersect_analytic for rays a .. b - 1 (tfar[i], or tfar[0] for all when it has one
    entry), written at their indices: t or inf, mirror index or -1."""
    for i in range(a, b):
        _nearest_into(i, origins, directions, tfar, kind, params, edges, tmin, t_out, idx_out)


@njit(cache=True, inline="always")
def intersect_rows(a, b, j0, per_row, spp, boxes, origins, directions, tfar, kind, params,
                   edges, tmin, t_out, idx_out):
    """intersect_range for primary rays a .. b - 1, image rows j0 onward (per_row rays a
    row, spp a pixel): in each row only the rays of pixels within some mirror's
    `screen_boxes` box are traced (all mirrors, as intersect_range traces them); the others
    can meet none and get a miss."""
    j = j0
    for first in range(a, b, per_row):
        last = min(b, first + per_row)
        lo, hi = per_row, 0  # the row's rays to trace, counted from the row's start
        for k in range(boxes.shape[0]):
            if boxes[k, 2] <= j < boxes[k, 3]:
                lo = min(lo, boxes[k, 0] * spp)
                hi = max(hi, boxes[k, 1] * spp)
        for n in range(first, last):
            i = np.uint64(n)  # unsigned, as in resolve.resolve_range
            if lo <= n - first < hi:
                _nearest_into(i, origins, directions, tfar, kind, params, edges, tmin, t_out,
                              idx_out)
            else:
                t_out[i] = np.inf
                idx_out[i] = -1
        j += 1


@njit(cache=True, inline="always")
def _nearest_into(i, origins, directions, tfar, kind, params, edges, tmin, t_out, idx_out):
    """Ray i's nearest analytic mirror in (tmin, tfar), worked in float64, into t_out[i]
    (float32; inf on a miss) and idx_out[i] (-1 on a miss)."""
    # np.float64, not float(): numba's float() keeps a float32 a float32
    f64 = np.float64
    ox, oy, oz = f64(origins[i, 0]), f64(origins[i, 1]), f64(origins[i, 2])
    dx, dy, dz = f64(directions[i, 0]), f64(directions[i, 1]), f64(directions[i, 2])
    best = f64(tfar[0] if tfar.shape[0] == 1 else tfar[i])
    found = -1
    for k in range(kind.shape[0]):
        if kind[k] == SPHERE:
            t = _sphere(ox, oy, oz, dx, dy, dz, params[k, SPHERE_CENTER],
                        params[k, SPHERE_CENTER + 1], params[k, SPHERE_CENTER + 2],
                        params[k, SPHERE_RADIUS], tmin)
        elif kind[k] == CYLINDER:
            t = _cylinder(ox, oy, oz, dx, dy, dz, params, k, tmin)
        elif kind[k] == PLANAR:
            t = _quad(ox, oy, oz, dx, dy, dz, params, edges, k, tmin)
        else:
            continue
        if t < best:
            best = t
            found = k
    if found >= 0:
        t_out[i] = best
        idx_out[i] = found
    else:
        t_out[i] = np.inf
        idx_out[i] = -1
