"""Sphere (disk) maps, derived from a cube map, with the mapping of the lecture notes.

Map space: the disk image of a mirror ball seen orthographically along -z (viewer direction
v = (0, 0, 1) in world axes). A direction r maps to
    (s, t) = (rx, ry) / sqrt(rx^2 + ry^2 + (rz + 1)^2)   in [-1, 1]^2,
then to texel coordinates ((s + 1) / 2, (1 - t) / 2) (row 0 at the top). The disk's rim is
r = (0, 0, -1), the direction straight away from the viewer: it is sampled worst.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .cube import cube_sample, face_bases, image_sample


def sphere_from_cube(faces: np.ndarray, resolution: int) -> np.ndarray:
    """(R, R, 3) sphere map sampled bilinearly from a cube map; black outside the disk."""
    out = np.zeros((resolution, resolution, 3), np.float32)
    _sphere_from_cube(faces, face_bases(), out)
    return out


@njit(cache=True, parallel=True)
def _sphere_from_cube(faces, bases, out):
    res = out.shape[0]
    for j in prange(res):
        t = 1.0 - 2.0 * (j + 0.5) / res
        for i in range(res):
            s = 2.0 * (i + 0.5) / res - 1.0
            q = 1.0 - s * s - t * t
            if q < 0.0:
                continue
            nz = math.sqrt(q)
            # r = 2 (n . v) n - v with v = (0, 0, 1)
            c = cube_sample(faces, bases, 2.0 * nz * s, 2.0 * nz * t, 2.0 * nz * nz - 1.0, True)
            out[j, i, 0] = c[0]
            out[j, i, 1] = c[1]
            out[j, i, 2] = c[2]


@njit(cache=True)
def sphere_coords(rx, ry, rz):
    """Texel coordinates (u, v) in [0, 1]^2 of direction r (need not be unit)."""
    length = math.sqrt(rx * rx + ry * ry + rz * rz)
    rx, ry, rz = rx / length, ry / length, rz / length
    m = math.sqrt(rx * rx + ry * ry + (rz + 1.0) * (rz + 1.0))
    if m == 0.0:
        return 1.0, 0.5  # r = (0, 0, -1): anywhere on the rim
    return (rx / m + 1.0) * 0.5, (1.0 - ry / m) * 0.5


@njit(cache=True)
def sphere_sample(image, rx, ry, rz, bilinear):
    u, v = sphere_coords(rx, ry, rz)
    return image_sample(image, u, v, bilinear)
