"""Hit resolution of one wave of rays: shade each ray's nearest hit into its pixel's color and
emit the reflected rays of mirror hits (a numba kernel over a range of rays).

A ray's color accumulates along its path: at an object, weight * shade; at a mirror,
weight * (1 - r) * base, and the weight becomes weight * r for the reflected ray; on a miss,
weight * background.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..scene.types import (
    CYLINDER_AXIS,
    CYLINDER_ORIGIN,
    MIRROR_TIE,
    PLANAR,
    PLANE_NORMAL,
    SPHERE,
    SPHERE_CENTER,
    UNLIT,
)
from ..shading import material_albedo, surface_color


@njit(cache=True, inline="always")
def _ray(origins, dirs, i):
    """Ray i's origin and direction in float64 (read only where a hit needs them: an unlit
    object hit does not)."""
    f64 = np.float64
    return (f64(origins[i, 0]), f64(origins[i, 1]), f64(origins[i, 2]),
            f64(dirs[i, 0]), f64(dirs[i, 1]), f64(dirs[i, 2]))


@njit(cache=True, inline="always")
def _add(color, s, c, x, first):
    """color[s, c] += x, or = x on the first wave (its rows start empty)."""
    if first:
        color[s, c] = x
    else:
        color[s, c] += x


@njit(cache=True)
def _pick(t_o, t_m, t_a):
    """0: object, 1: mirror triangle, 2: analytic mirror, -1: miss. Mirrors win depth ties."""
    best = t_o
    which = 0 if t_o < np.inf else -1
    if t_m * MIRROR_TIE <= best:
        best = t_m * MIRROR_TIE
        which = 1 if t_m < np.inf else which
    if t_a * MIRROR_TIE <= best and t_a < np.inf:
        which = 2
    return which


@njit(cache=True)
def planar_units(kind, params):
    """(M, 3) float64: each planar mirror's unit normal (rows of other mirrors unset), by the
    same expression resolve_range would use per ray (the same bits)."""
    unit = np.empty((kind.shape[0], 3))
    for k in range(kind.shape[0]):
        if kind[k] == PLANAR:
            gx, gy, gz = (params[k, PLANE_NORMAL], params[k, PLANE_NORMAL + 1],
                          params[k, PLANE_NORMAL + 2])
            inv = 1.0 / np.sqrt(gx * gx + gy * gy + gz * gz)
            unit[k, 0], unit[k, 1], unit[k, 2] = gx * inv, gy * inv, gz * inv
    return unit


@njit(cache=True, inline="always")
def resolve_range(lo, hi, rays, object_hits, mirror_hits, analytic_hits, surfaces, follow, color,
                  hits, out_rays, out_start, first):
    """Shade the nearest hits of rays lo .. hi - 1 into color[slot] (hit_t and hit_surface at
    the rays' indices) and emit their reflected rays, in order, into the out arrays from
    out_start on (ray, weight, slot); returns how many. A reflected ray lives on while any
    channel of its weight is positive.

    Inputs are float32; hit points and reflected directions are worked in float64
    (np.float64(), since numba's float() keeps a float32 a float32). `first`: the primary
    wave, whose weights are ones and slots the identity (neither array is read) and whose
    color rows are written rather than added to (the same numbers: 0 + x is x, 1 * x is x;
    `color` may then hold anything before).

    Arguments are tuples (numba inlines no call of more than 30 arguments): rays (origins,
    dirs, weight, slot); the hits (t, primitive, u, v) of objects and of mesh mirrors and
    (t, mirror) of analytic ones; surfaces (objects' corners, uvs, normals, material,
    surface; mesh mirrors' corners, normals, surface; mirrors' kind, params, reflectance,
    base; n_objects; mat_i, mat_f, texels, light_f, shading, ambient, background; the
    mirrors' `planar_units`, made once a frame, not once a wave of a segment); hits
    (hit_t, hit_surface); out_rays (origins, dirs, weights, slots)."""
    origins, dirs, weight, slot = rays
    t_o, p_o, u_o, v_o = object_hits
    t_m, p_m, u_m, v_m = mirror_hits
    t_a, k_a = analytic_hits
    (corners, uvs, normals, material, surface, m_corners, m_normals, m_surface, m_kind,
     m_params, m_refl, m_base, n_objects, mat_i, mat_f, texels, light_f, shading, ambient,
     background, unit) = surfaces
    hit_t, hit_surface = hits
    out_o, out_d, out_w, out_slot = out_rays
    j = np.uint64(out_start)
    # indices as unsigned integers (all are >= 0 here): numba then leaves out each signed
    # index's test for a negative value (Python's wraparound) at every array access; the
    # tracer's other per-ray loops and shading.material_albedo do the same
    for n in range(hi - lo):
        i = np.uint64(lo + n)
        if first:
            s = i
            w = (np.float32(1.0), np.float32(1.0), np.float32(1.0))
        else:
            s = np.uint64(slot[i])
            w = (weight[i, 0], weight[i, 1], weight[i, 2])
        which = _pick(t_o[i], t_m[i], t_a[i])
        if which < 0:
            hit_t[i] = np.inf
            hit_surface[i] = -1
            for c in range(3):
                _add(color, s, c, w[c] * background[c], first)
            continue
        if which == 0:
            t = np.float64(t_o[i])
            tri = np.uint64(p_o[i])
            b1, b2 = np.float64(u_o[i]), np.float64(v_o[i])
            b0 = 1.0 - b1 - b2
            hit_t[i] = t
            hit_surface[i] = surface[tri]
            u = b0 * uvs[tri, 0, 0] + b1 * uvs[tri, 1, 0] + b2 * uvs[tri, 2, 0]
            v = b0 * uvs[tri, 0, 1] + b1 * uvs[tri, 1, 1] + b2 * uvs[tri, 2, 1]
            if shading == UNLIT:  # the albedo: no hit point, no normal to interpolate
                r, g, b = material_albedo(material[tri], u, v, mat_i, mat_f, texels)
            else:
                ox, oy, oz, dx, dy, dz = _ray(origins, dirs, i)
                px, py, pz = ox + t * dx, oy + t * dy, oz + t * dz
                nx = b0 * normals[tri, 0, 0] + b1 * normals[tri, 1, 0] + b2 * normals[tri, 2, 0]
                ny = b0 * normals[tri, 0, 1] + b1 * normals[tri, 1, 1] + b2 * normals[tri, 2, 1]
                nz = b0 * normals[tri, 0, 2] + b1 * normals[tri, 1, 2] + b2 * normals[tri, 2, 2]
                r, g, b = surface_color(material[tri], u, v, px, py, pz, nx, ny, nz, dx, dy, dz,
                                        mat_i, mat_f, texels, light_f, shading, ambient)
            _add(color, s, 0, w[0] * r, first)
            _add(color, s, 1, w[1] * g, first)
            _add(color, s, 2, w[2] * b, first)
            continue
        # a mirror: geometric normal (for the offset) and shading normal (for the reflection)
        ox, oy, oz, dx, dy, dz = _ray(origins, dirs, i)
        if which == 1:
            t = np.float64(t_m[i])
            tri = np.uint64(p_m[i])
            planar = False
            k = np.uint64(m_surface[tri] - n_objects)
            b1, b2 = np.float64(u_m[i]), np.float64(v_m[i])
            b0 = 1.0 - b1 - b2
            e1x = m_corners[tri, 1, 0] - m_corners[tri, 0, 0]
            e1y = m_corners[tri, 1, 1] - m_corners[tri, 0, 1]
            e1z = m_corners[tri, 1, 2] - m_corners[tri, 0, 2]
            e2x = m_corners[tri, 2, 0] - m_corners[tri, 0, 0]
            e2y = m_corners[tri, 2, 1] - m_corners[tri, 0, 1]
            e2z = m_corners[tri, 2, 2] - m_corners[tri, 0, 2]
            gx, gy, gz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
            nx = b0 * m_normals[tri, 0, 0] + b1 * m_normals[tri, 1, 0] + b2 * m_normals[tri, 2, 0]
            ny = b0 * m_normals[tri, 0, 1] + b1 * m_normals[tri, 1, 1] + b2 * m_normals[tri, 2, 1]
            nz = b0 * m_normals[tri, 0, 2] + b1 * m_normals[tri, 1, 2] + b2 * m_normals[tri, 2, 2]
            px, py, pz = ox + t * dx, oy + t * dy, oz + t * dz
        else:
            t = np.float64(t_a[i])
            k = np.uint64(k_a[i])
            planar = m_kind[k] == PLANAR
            px, py, pz = ox + t * dx, oy + t * dy, oz + t * dz
            if m_kind[k] == PLANAR:
                gx = m_params[k, PLANE_NORMAL]
                gy = m_params[k, PLANE_NORMAL + 1]
                gz = m_params[k, PLANE_NORMAL + 2]
            elif m_kind[k] == SPHERE:
                gx = px - m_params[k, SPHERE_CENTER]
                gy = py - m_params[k, SPHERE_CENTER + 1]
                gz = pz - m_params[k, SPHERE_CENTER + 2]
            else:  # CYLINDER: radial direction from the axis
                lx = px - m_params[k, CYLINDER_ORIGIN]
                ly = py - m_params[k, CYLINDER_ORIGIN + 1]
                lz = pz - m_params[k, CYLINDER_ORIGIN + 2]
                ax = m_params[k, CYLINDER_AXIS]
                ay = m_params[k, CYLINDER_AXIS + 1]
                az = m_params[k, CYLINDER_AXIS + 2]
                h = lx * ax + ly * ay + lz * az
                gx, gy, gz = lx - h * ax, ly - h * ay, lz - h * az
            nx, ny, nz = gx, gy, gz
        hit_t[i] = t
        hit_surface[i] = n_objects + np.int64(k)
        for c in range(3):
            _add(color, s, c, w[c] * (1.0 - m_refl[k, c]) * m_base[k, c], first)
        if not follow:
            continue
        # face both normals toward the incoming ray (mirrors are two-sided), unit length
        if planar:  # n = g: the unit normal, turned (-x * inv is -(x * inv), bit for bit)
            sign = -1.0 if gx * dx + gy * dy + gz * dz > 0.0 else 1.0
            gx, gy, gz = sign * unit[k, 0], sign * unit[k, 1], sign * unit[k, 2]
            nx, ny, nz = gx, gy, gz
        else:
            if gx * dx + gy * dy + gz * dz > 0.0:
                gx, gy, gz = -gx, -gy, -gz
            if nx * dx + ny * dy + nz * dz > 0.0:
                nx, ny, nz = -nx, -ny, -nz
            inv = 1.0 / np.sqrt(nx * nx + ny * ny + nz * nz)
            nx, ny, nz = nx * inv, ny * inv, nz * inv
            inv = 1.0 / np.sqrt(gx * gx + gy * gy + gz * gz)
            gx, gy, gz = gx * inv, gy * inv, gz * inv
        dn = dx * nx + dy * ny + dz * nz
        rx, ry, rz = dx - 2.0 * dn * nx, dy - 2.0 * dn * ny, dz - 2.0 * dn * nz
        inv = 1.0 / np.sqrt(rx * rx + ry * ry + rz * rz)
        rx, ry, rz = rx * inv, ry * inv, rz * inv
        # start the reflected ray a little off the surface (eps, scaled to the coordinates'
        # magnitude), moving along the ray itself so that it stays on the exact reflected line
        eps = 1e-4 * (1.0 + max(abs(px), abs(py), abs(pz)))
        step = eps / max(rx * gx + ry * gy + rz * gz, 1e-2)
        w0, w1, w2 = w[0] * m_refl[k, 0], w[1] * m_refl[k, 1], w[2] * m_refl[k, 2]
        if not (w0 > 0.0 or w1 > 0.0 or w2 > 0.0):
            continue
        out_o[j, 0], out_o[j, 1], out_o[j, 2] = px + step * rx, py + step * ry, pz + step * rz
        out_d[j, 0], out_d[j, 1], out_d[j, 2] = rx, ry, rz
        out_w[j, 0], out_w[j, 1], out_w[j, 2] = w0, w1, w2
        out_slot[j] = s
        j += np.uint64(1)
    return np.int64(j) - out_start
