"""Per-pixel environment-map lookup on a reflector's pixels (numba).

For each pixel the rasterizer gave to the reflector: the world-space point p and normal n
(exact for planes, spheres and cylinders, interpolated for meshes), the view vector
v = (eye - p)/|eye - p|, the reflection r = 2 n (n.v) - v, optionally corrected for parallax
by a proxy box (the direction from the capture point to where the ray p + t r leaves the box),
and the map's color in that direction, added with the mirror's reflectance.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

from ..parallel import claim_rows, counter
from ..reflection import reflected_ray
from .cube import cube_sample
from .sphere import sphere_sample

CUBE, SPHERE_MAP = 0, 1


def add_reflections(rgb, buffers, surface_ids, surface, tris, kind, params, reflectance, eye,
                    capture, box_lo, box_hi, parallax, map_kind, faces, sphere, bases, bilinear):
    """rgb[pixels of `surface`] += reflectance * map(reflection direction); in place."""
    _add(rgb, buffers.triangle, buffers.b1, buffers.b2, surface_ids, surface, tris.corners,
         tris.normals, kind, params, reflectance, np.asarray(eye, np.float64),
         np.asarray(capture, np.float64), np.asarray(box_lo, np.float64),
         np.asarray(box_hi, np.float64), parallax, map_kind, faces, sphere, bases, bilinear,
         numba.get_num_threads())


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
         lo, hi, parallax, map_kind, faces, sphere, bases, bilinear, threads):
    """Bands of rows claimed by whichever thread is free (parallel.py): a mirror's pixels
    bunch in some rows, and a pixel's result is its own whoever looks it up."""
    h, w = tri.shape
    claimed = counter()
    for _worker in prange(threads):
        y0, y1 = claim_rows(claimed, h)
        while y0 < y1:
            for y in range(y0, y1):
                _add_row(y, w, rgb, tri, b1, b2, surface_ids, surface, corners, normals, kind,
                         p, refl, eye, capture, lo, hi, parallax, map_kind, faces, sphere,
                         bases, bilinear)
            y0, y1 = claim_rows(claimed, h)


@njit(cache=True)
def _add_row(y, w, rgb, tri, b1, b2, surface_ids, surface, corners, normals, kind, p, refl,
             eye, capture, lo, hi, parallax, map_kind, faces, sphere, bases, bilinear):
    """_add's pixels of `surface` in row y."""
    for x in range(w):
        if surface_ids[y, x] != surface:
            continue
        px, py, pz, rx, ry, rz, _ = reflected_ray(tri[y, x], b1[y, x], b2[y, x], corners,
                                                  normals, kind, p, eye)
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
