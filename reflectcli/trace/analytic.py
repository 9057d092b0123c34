"""Exact ray intersection with sphere and open-cylinder mirrors (world space, numba)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..scene.types import CYLINDER, SPHERE


def intersect_analytic(
    origins: np.ndarray, directions: np.ndarray, tfar: np.ndarray, kind: np.ndarray,
    params: np.ndarray, tmin: float
) -> tuple[np.ndarray, np.ndarray]:
    """Nearest analytic-mirror hit per ray in (tmin, tfar): (t or inf, mirror index or -1)."""
    n = origins.shape[0]
    t = np.full(n, np.inf, np.float32)
    idx = np.full(n, -1, np.int32)
    if np.any((kind == SPHERE) | (kind == CYLINDER)):
        params = np.ascontiguousarray(params, dtype=np.float64)
        _intersect(origins, directions, tfar, kind, params, tmin, t, idx)
    return t, idx


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
def _cylinder(ox, oy, oz, dx, dy, dz, p, tmin):
    """Smallest t > tmin on the open tube (origin p[0:3], unit axis p[3:6], radius, height)."""
    ax, ay, az = p[3], p[4], p[5]
    lx, ly, lz = ox - p[0], oy - p[1], oz - p[2]
    dd = dx * ax + dy * ay + dz * az
    ld = lx * ax + ly * ay + lz * az
    # components perpendicular to the axis
    ux, uy, uz = dx - dd * ax, dy - dd * ay, dz - dd * az
    wx, wy, wz = lx - ld * ax, ly - ld * ay, lz - ld * az
    a = ux * ux + uy * uy + uz * uz
    if a == 0.0:
        return np.inf
    b = ux * wx + uy * wy + uz * wz
    c = wx * wx + wy * wy + wz * wz - p[6] * p[6]
    disc = b * b - a * c
    if disc < 0.0:
        return np.inf
    s = math.sqrt(disc)
    for sign in (-1.0, 1.0):
        t = (-b + sign * s) / a
        if t > tmin:
            h = ld + t * dd
            if 0.0 <= h <= p[7]:
                return t
    return np.inf


@njit(cache=True, parallel=True)
def _intersect(origins, directions, tfar, kind, params, tmin, t_out, idx_out):
    for i in prange(origins.shape[0]):
        ox, oy, oz = float(origins[i, 0]), float(origins[i, 1]), float(origins[i, 2])
        dx, dy, dz = float(directions[i, 0]), float(directions[i, 1]), float(directions[i, 2])
        best = float(tfar[i])
        found = -1
        for k in range(kind.shape[0]):
            p = params[k]
            if kind[k] == SPHERE:
                t = _sphere(ox, oy, oz, dx, dy, dz, p[0], p[1], p[2], p[3], tmin)
            elif kind[k] == CYLINDER:
                t = _cylinder(ox, oy, oz, dx, dy, dz, p, tmin)
            else:
                continue
            if t < best:
                best = t
                found = k
        if found >= 0:
            t_out[i] = best
            idx_out[i] = found
