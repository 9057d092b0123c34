"""The reflected ray at a reflector's pixel: one kernel helper that every technique shading a
mirror pixel from its item buffer (envmap's lookup, distance maps, screen-space rays) calls,
so that all of them reflect about the same normal as the ray tracer."""

from __future__ import annotations

import math

from numba import njit

from .scene.types import (
    CYLINDER,
    CYLINDER_AXIS,
    CYLINDER_ORIGIN,
    PLANAR,
    PLANE_NORMAL,
    SPHERE,
    SPHERE_CENTER,
)


@njit(cache=True)
def reflected_ray(tri, b1, b2, corners, normals, kind, p, eye):
    """(px, py, pz, rx, ry, rz, cos): the world point at barycentrics (b1, b2) of triangle
    `tri` of a reflector of `kind` (mirror parameters `p`), the eye ray reflected there
    (unit: 2 (n.v) n - v) and n.v. Exact normals for planes, spheres and cylinders,
    interpolated ones for meshes; two-sided, so the normal is turned toward the viewer."""
    c1 = b1
    c2 = b2
    c0 = 1.0 - c1 - c2
    t = tri
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
        d = lx * ax + ly * ay + lz * az
        nx, ny, nz = lx - d * ax, ly - d * ay, lz - d * az
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
    return px, py, pz, 2.0 * nv * nx - vx, 2.0 * nv * ny - vy, 2.0 * nv * nz - vz, nv
