"""Exact virtual vertices on extrusion mirrors with a known profile (numba, world space);
spheres and cylinders are in circle.py.

General linear extrusion (`method = "extrusion"` on an extrusion mirror, the TV of Fig. 17):
the 2-D problem of circle.py (f = n x u_E + n x u_Q = 0 in the cross-section) against the
profile polyline with normals interpolated along it: the sign of f at the profile's
vertices finds the segment holding the reflection point (the coarse level of the paper's
binary-search hierarchy), bisection finds it within. Where no segment brackets a root (the
point's reflection lies off the profile's ends), the nearer end is used: a doubly virtual
vertex. Works in the extrusion's local frame, so the transform must be a similarity
(uniform scale).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


def profile_virtual_vertices(points: np.ndarray, eye: np.ndarray, profile: np.ndarray,
                             normals: np.ndarray, world_from_local: np.ndarray):
    """(virtual points (N, 3), hidden (N,) bool) for a linear extrusion of `profile`
    (local x, z); points, eye and the result in world space."""
    local_from_world = np.linalg.inv(world_from_local)
    local = np.ascontiguousarray(
        points @ local_from_world[:3, :3].T + local_from_world[:3, 3], np.float64)
    e = local_from_world[:3, :3] @ np.asarray(eye, np.float64) + local_from_world[:3, 3]
    out = np.empty(points.shape, np.float64)
    hidden = np.empty(points.shape[0], np.bool_)
    _profile_many(local, e, np.ascontiguousarray(profile, np.float64),
                  np.ascontiguousarray(normals, np.float64), out, hidden)
    return out @ world_from_local[:3, :3].T + world_from_local[:3, 3], hidden


@njit(cache=True)
def _profile_at(profile, normals, t):
    """Point and unit normal at parameter t in [0, N - 1] along the polyline."""
    last = profile.shape[0] - 1
    s = min(int(math.floor(t)), last - 1)
    a = t - s
    jx = (1 - a) * profile[s, 0] + a * profile[s + 1, 0]
    jz = (1 - a) * profile[s, 1] + a * profile[s + 1, 1]
    nx = (1 - a) * normals[s, 0] + a * normals[s + 1, 0]
    nz = (1 - a) * normals[s, 1] + a * normals[s + 1, 1]
    inv = 1.0 / math.sqrt(nx * nx + nz * nz)
    return jx, jz, nx * inv, nz * inv


@njit(cache=True)
def _law(profile, normals, t, ex, ez, qx, qz):
    """f(t) = n x u_E + n x u_Q (2-D): zero at a reflection point."""
    jx, jz, nx, nz = _profile_at(profile, normals, t)
    ux, uz = ex - jx, ez - jz
    inv = 1.0 / max(math.sqrt(ux * ux + uz * uz), 1e-300)
    vx, vz = qx - jx, qz - jz
    inv2 = 1.0 / max(math.sqrt(vx * vx + vz * vz), 1e-300)
    return (nx * uz * inv - nz * ux * inv) + (nx * vz * inv2 - nz * vx * inv2)


@njit(cache=True, parallel=True)
def _profile_many(points, e, profile, normals, out, hidden):
    for i in prange(points.shape[0]):
        x, y, z, h = _profile_one(points[i, 0], points[i, 1], points[i, 2], e, profile, normals)
        out[i, 0] = x
        out[i, 1] = y
        out[i, 2] = z
        hidden[i] = h


@njit(cache=True)
def _profile_one(qx, qy, qz, e, profile, normals):
    """(Q' x, y, z, hidden) in the extrusion's local frame (y along the extrusion)."""
    last = profile.shape[0] - 1
    # hidden: the line of sight (2-D) crosses the profile before reaching Q
    t_hit = 2.0
    param = -1.0
    for s in range(last):
        ax, az = profile[s, 0], profile[s, 1]
        sx, sz = profile[s + 1, 0] - ax, profile[s + 1, 1] - az
        dx, dz = qx - e[0], qz - e[2]
        den = dx * sz - dz * sx
        if den == 0.0:
            continue
        t = ((ax - e[0]) * sz - (az - e[2]) * sx) / den
        u = ((ax - e[0]) * dz - (az - e[2]) * dx) / den
        if 0.0 < t < t_hit and 0.0 <= u <= 1.0:
            t_hit = t
            param = s + u
    hidden = param >= 0.0
    if not hidden:
        # coarse level: the segment whose ends bracket a sign change of f
        lo = -1.0
        hi = -1.0
        f_prev = _law(profile, normals, 0.0, e[0], e[2], qx, qz)
        best = 0.0
        best_f = abs(f_prev)
        for s in range(1, last + 1):
            f = _law(profile, normals, float(s), e[0], e[2], qx, qz)
            if abs(f) < best_f:
                best = float(s)
                best_f = abs(f)
            if (f_prev > 0.0) != (f > 0.0):
                lo = float(s - 1)
                hi = float(s)
                break
            f_prev = f
        if lo < 0.0:
            param = best
        else:
            f_lo = _law(profile, normals, lo, e[0], e[2], qx, qz)
            for _ in range(40):
                mid = 0.5 * (lo + hi)
                f_mid = _law(profile, normals, mid, e[0], e[2], qx, qz)
                if (f_mid > 0.0) == (f_lo > 0.0):
                    lo = mid
                    f_lo = f_mid
                else:
                    hi = mid
            param = 0.5 * (lo + hi)
    jx, jz, nx, nz = _profile_at(profile, normals, param)
    dist = (qx - jx) * nx + (qz - jz) * nz
    return qx - 2.0 * dist * nx, qy, qz - 2.0 * dist * nz, hidden
