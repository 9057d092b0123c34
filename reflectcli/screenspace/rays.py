"""Reflected rays of a frame's mirror pixels, in eye space and on the screen (numba).

Spaces: world -> eye (camera at the origin looking down -z; depth = -z, the Z channel)
-> screen (x right, y down, pixels [i, i+1); the projection of `Camera.projection_matrix`).
Along a straight eye-space segment, screen x, y and q = 1 / depth are affine in one
parameter u in [0, 1] (perspective-correct interpolation, McGuire & Mara 2014 sec. 2.2: their
k = 1/w with w = -z = depth); every march works on (x, y, q).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

from ..parallel import claim_rows, counter
from ..reflection import reflected_ray

# columns of the per-pixel ray table
# 0-2 world origin, 3-5 world unit direction, 6-8 eye origin, 9-11 eye direction,
# 12 n.v (cosine between normal and view vector), 13 ray length L (clipped at the near plane),
# 14-16 screen start (x, y, q), 17-19 screen end (x, y, q)
RAY_COLS = 20
# mirror_rays' arrays in a workspace kept across frames
TABLE = "mirror_rays"
VALID = "mirror_rays_valid"


def mirror_rays(buffers, surface_ids, n_objects, tris, mirrors, camera, max_distance,
                workspace=None):
    """(rays (H, W, RAY_COLS) float32, valid (H, W) bool): one reflected ray per mirror pixel.

    The ray starts at the mirror pixel's point (barycentric on the rasterized triangle) with
    the mirror's normal there (exact for planes, spheres and cylinders, interpolated for
    meshes), turned toward the viewer: r = 2 n (n.v) - v. It is `max_distance` long, clipped
    where it would cross the near plane.

    `workspace` (a RasterWorkspace): both arrays are its own, kept from frame to frame (the
    table is 24.6 MB at 640 x 480, faulted in again each frame when fresh), valid until the
    next call. Each call writes `valid` whole and every mirror pixel's row (its ray, or
    zeros where no ray starts: what a fresh table held); the rows of other pixels keep what
    an earlier frame (or the allocator) left, and nothing reads them: ssr's marches,
    `confidence` and `resolve_hits` read the rows of `valid` pixels only (a hit is a valid
    pixel's: the hit array is kept too (`march.outputs`), and the marches and ppr's `decode`
    write NO_HIT at every pixel without a ray or a source), ppr's `decode`
    and `resolve_hits` the rows of pixels holding a source (mirror pixels: scatter_min
    targets only pixels of the mirror, fill_holes fills only mirror pixels). Without a
    workspace the arrays are fresh (zeros where not written).
    """
    h, w = surface_ids.shape
    if workspace is None:
        rays = np.zeros((h, w, RAY_COLS), np.float32)
        valid = np.zeros((h, w), np.bool_)
    else:
        rays = workspace.get(TABLE, (h, w, RAY_COLS), np.float32)
        valid = workspace.get(VALID, (h, w), np.bool_)
    p = camera.projection_matrix()
    _rays(buffers.triangle, buffers.b1, buffers.b2, surface_ids, n_objects, tris.corners,
          tris.normals, mirrors.kind, mirrors.params, camera.view_matrix(),
          np.asarray(camera.eye, np.float64), float(p[0, 0]), float(p[1, 1]), w, h,
          float(camera.near), float(max_distance), rays, valid, numba.get_num_threads())
    return rays, valid


@njit(cache=True)
def to_screen(xe, ye, ze, p00, p11, w, h):
    """Eye-space point -> (screen x, screen y, q = 1 / depth)."""
    depth = -ze
    q = 1.0 / depth
    sx = (p00 * xe * q + 1.0) * 0.5 * w
    sy = (1.0 - p11 * ye * q) * 0.5 * h
    return sx, sy, q


@njit(cache=True, parallel=True)
def _rays(tri, b1, b2, surface_ids, n_objects, corners, normals, kind, params, view, eye,
          p00, p11, w, h, near, max_distance, rays, valid, threads):
    """Bands of rows claimed by whichever thread is free (parallel.py): the mirror pixels
    bunch in some rows, and a pixel's ray is its own whoever makes it."""
    claimed = counter()
    for _worker in prange(threads):
        y0, y1 = claim_rows(claimed, h)
        while y0 < y1:
            for y in range(y0, y1):
                _rays_row(y, tri, b1, b2, surface_ids, n_objects, corners, normals, kind,
                          params, view, eye, p00, p11, w, h, near, max_distance, rays, valid)
            y0, y1 = claim_rows(claimed, h)


@njit(cache=True)
def _rays_row(y, tri, b1, b2, surface_ids, n_objects, corners, normals, kind, params, view,
              eye, p00, p11, w, h, near, max_distance, rays, valid):
    """_rays' row y: `valid` for every pixel, the table's row for every mirror pixel (its
    ray, or zeros); other pixels' rows are not written (mirror_rays says who reads what)."""
    for x in range(w):
        valid[y, x] = False
        s = surface_ids[y, x]
        if s < n_objects:
            continue
        k = s - n_objects
        px, py, pz, rx, ry, rz, nv = reflected_ray(tri[y, x], b1[y, x], b2[y, x], corners,
                                                   normals, kind[k], params[k], eye)
        inv = 1.0 / math.sqrt(rx * rx + ry * ry + rz * rz)
        rx, ry, rz = rx * inv, ry * inv, rz * inv
        # eye space
        ox = view[0, 0] * px + view[0, 1] * py + view[0, 2] * pz + view[0, 3]
        oy = view[1, 0] * px + view[1, 1] * py + view[1, 2] * pz + view[1, 3]
        oz = view[2, 0] * px + view[2, 1] * py + view[2, 2] * pz + view[2, 3]
        dx = view[0, 0] * rx + view[0, 1] * ry + view[0, 2] * rz
        dy = view[1, 0] * rx + view[1, 1] * ry + view[1, 2] * rz
        dz = view[2, 0] * rx + view[2, 1] * ry + view[2, 2] * rz
        length = max_distance
        if oz + dz * length > -near:  # would cross the near plane (depth = -z < near)
            length = (-near - oz) / dz if dz > 0.0 else length
        r = rays[y, x]
        if length <= 0.0 or -oz < near:
            r[:] = 0.0  # no ray; ppr's decode still reads a reached pixel's origin
            continue
        r[0], r[1], r[2] = px, py, pz
        r[3], r[4], r[5] = rx, ry, rz
        r[6], r[7], r[8] = ox, oy, oz
        r[9], r[10], r[11] = dx, dy, dz
        r[12] = nv
        r[13] = length
        r[14], r[15], r[16] = to_screen(ox, oy, oz, p00, p11, w, h)
        r[17], r[18], r[19] = to_screen(ox + dx * length, oy + dy * length,
                                        oz + dz * length, p00, p11, w, h)
        valid[y, x] = True


@njit(cache=True)
def distance_at(r, u):
    """Eye-space distance from the ray's origin to its point at screen parameter u."""
    q0 = r[16]
    q1 = r[19]
    q = q0 + u * (q1 - q0)
    return u * q1 / q * r[13]
