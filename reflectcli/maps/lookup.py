"""Per-pixel environment-map lookup on a reflector's pixels (numba).

For each pixel the rasterizer gave to the reflector: the world-space point p and normal n
(exact for planes, spheres and cylinders, interpolated for meshes), the view vector
v = (eye - p)/|eye - p|, the reflection r = 2 n (n.v) - v, optionally corrected for parallax
by a proxy box (the direction from the capture point to where the ray p + t r leaves the box),
and the map's color in that direction, added with the mirror's reflectance.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..scene.types import (
    CYLINDER,
    CYLINDER_AXIS,
    CYLINDER_ORIGIN,
    PLANAR,
    PLANE_NORMAL,
    SPHERE,
    SPHERE_CENTER,
)
from .cube import cube_sample
from .sphere import sphere_sample

CUBE, SPHERE_MAP = 0, 1


def add_reflections(rgb, buffers, surface_ids, surface, tris, kind, params, reflectance, eye,
                    capture, box_lo, box_hi, parallax, map_kind, faces, sphere, bases, bilinear):
    """rgb[pixels of `surface`] += reflectance * map(reflection direction); in place."""
    _add(rgb, buffers.triangle, buffers.b1, buffers.b2, surface_ids, surface, tris.corners,
         tris.normals, kind, params, reflectance, np.asarray(eye, np.float64),
         np.asarray(capture, np.float64), np.asarray(box_lo, np.float64),
         np.asarray(box_hi, np.float64), parallax, map_kind, faces, sphere, bases, bilinear)


@njit(cache=True)
def box_exit(px, py, pz, rx, ry, rz, lo, hi):
    """t at which the ray p + t r leaves the box [lo, hi], or -1 if p is outside it.

    A point on a face (a mirror hung on the room's wall) counts as inside: p is clamped to
    the box within 1e-4 of its size, so rounding never flips it out."""
    p = (px, py, pz)
    r = (rx, ry, rz)
    t_exit = np.inf
    for a in range(3):
        tol = 1e-4 * (hi[a] - lo[a])
        if p[a] < lo[a] - tol or p[a] > hi[a] + tol:
            return -1.0
        q = min(max(p[a], lo[a]), hi[a])
        if r[a] > 0.0:
            t_exit = min(t_exit, (hi[a] - q) / r[a])
        elif r[a] < 0.0:
            t_exit = min(t_exit, (lo[a] - q) / r[a])
    return max(t_exit, 0.0)


@njit(cache=True, parallel=True)
def _add(rgb, tri, b1, b2, surface_ids, surface, corners, normals, kind, p, refl, eye, capture,
         lo, hi, parallax, map_kind, faces, sphere, bases, bilinear):
    h, w = tri.shape
    for y in prange(h):
        for x in range(w):
            if surface_ids[y, x] != surface:
                continue
            t = tri[y, x]
            c1 = b1[y, x]
            c2 = b2[y, x]
            c0 = 1.0 - c1 - c2
            px = c0 * corners[t, 0, 0] + c1 * corners[t, 1, 0] + c2 * corners[t, 2, 0]
            py = c0 * corners[t, 0, 1] + c1 * corners[t, 1, 1] + c2 * corners[t, 2, 1]
            pz = c0 * corners[t, 0, 2] + c1 * corners[t, 1, 2] + c2 * corners[t, 2, 2]
            if kind == PLANAR:
                nx, ny, nz = p[PLANE_NORMAL], p[PLANE_NORMAL + 1], p[PLANE_NORMAL + 2]
            elif kind == SPHERE:
                nx = px - p[SPHERE_CENTER]
                ny = py - p[SPHERE_CENTER + 1]
                nz = pz - p[SPHERE_CENTER + 2]
            elif kind == CYLINDER:  # radial direction from the axis
                lx = px - p[CYLINDER_ORIGIN]
                ly = py - p[CYLINDER_ORIGIN + 1]
                lz = pz - p[CYLINDER_ORIGIN + 2]
                ax, ay, az = p[CYLINDER_AXIS], p[CYLINDER_AXIS + 1], p[CYLINDER_AXIS + 2]
                a = lx * ax + ly * ay + lz * az
                nx, ny, nz = lx - a * ax, ly - a * ay, lz - a * az
            else:
                nx = c0 * normals[t, 0, 0] + c1 * normals[t, 1, 0] + c2 * normals[t, 2, 0]
                ny = c0 * normals[t, 0, 1] + c1 * normals[t, 1, 1] + c2 * normals[t, 2, 1]
                nz = c0 * normals[t, 0, 2] + c1 * normals[t, 1, 2] + c2 * normals[t, 2, 2]
            inv = 1.0 / math.sqrt(nx * nx + ny * ny + nz * nz)
            nx, ny, nz = nx * inv, ny * inv, nz * inv
            vx, vy, vz = eye[0] - px, eye[1] - py, eye[2] - pz
            inv = 1.0 / math.sqrt(vx * vx + vy * vy + vz * vz)
            vx, vy, vz = vx * inv, vy * inv, vz * inv
            nv = nx * vx + ny * vy + nz * vz
            if nv < 0.0:  # two-sided: the normal faces the viewer
                nx, ny, nz, nv = -nx, -ny, -nz, -nv
            rx, ry, rz = 2.0 * nv * nx - vx, 2.0 * nv * ny - vy, 2.0 * nv * nz - vz
            if parallax:
                te = box_exit(px, py, pz, rx, ry, rz, lo, hi)
                if te > 0.0:
                    rx = px + te * rx - capture[0]
                    ry = py + te * ry - capture[1]
                    rz = pz + te * rz - capture[2]
            if map_kind == CUBE:
                c = cube_sample(faces, bases, rx, ry, rz, bilinear)
            else:
                c = sphere_sample(sphere, rx, ry, rz, bilinear)
            for k in range(3):
                rgb[y, x, k] += refl[k] * c[k]
