"""Colour of a screen-space hit, and the engines' confidence (numba).

`resolve = "pixel"` takes the primary frame's colour at the hit pixel (what the engines do:
one sample of the lit colour buffer). `resolve = "surface"` intersects the ray with the
plane of the triangle the primary pass left at the hit pixel and shades that point with the
shared shading (beyond the papers, like dprm's surface reconstruction): the colour is then
exact wherever the hit pixel's triangle is the surface the ray meets, so what is left of
the error against the ray tracer is the hit itself, not resampling.
"""

from __future__ import annotations

from numba import njit, prange

from ..shading import surface_color


@njit(cache=True)
def _surface_hit(t, ox, oy, oz, rx, ry, rz, corners, uvs, normals, material, mat_i, mat_f,
                 texels, light_f, shading, ambient):
    """(ok, distance, r, g, b): the ray meets triangle t's plane; shaded there."""
    ax, ay, az = corners[t, 0, 0], corners[t, 0, 1], corners[t, 0, 2]
    e1x, e1y, e1z = corners[t, 1, 0] - ax, corners[t, 1, 1] - ay, corners[t, 1, 2] - az
    e2x, e2y, e2z = corners[t, 2, 0] - ax, corners[t, 2, 1] - ay, corners[t, 2, 2] - az
    # Moller-Trumbore without the inside test: barycentrics may leave [0, 1] (the plane
    # continues the triangle's attributes affinely, exact for flat quads)
    px = ry * e2z - rz * e2y
    py = rz * e2x - rx * e2z
    pz = rx * e2y - ry * e2x
    det = e1x * px + e1y * py + e1z * pz
    if abs(det) < 1e-12:
        return False, 0.0, 0.0, 0.0, 0.0
    inv = 1.0 / det
    tx, ty, tz = ox - ax, oy - ay, oz - az
    b1 = (tx * px + ty * py + tz * pz) * inv
    qx = ty * e1z - tz * e1y
    qy = tz * e1x - tx * e1z
    qz = tx * e1y - ty * e1x
    b2 = (rx * qx + ry * qy + rz * qz) * inv
    dist = (e2x * qx + e2y * qy + e2z * qz) * inv
    if dist <= 0.0:
        return False, 0.0, 0.0, 0.0, 0.0
    b0 = 1.0 - b1 - b2
    u = b0 * uvs[t, 0, 0] + b1 * uvs[t, 1, 0] + b2 * uvs[t, 2, 0]
    v = b0 * uvs[t, 0, 1] + b1 * uvs[t, 1, 1] + b2 * uvs[t, 2, 1]
    hx, hy, hz = ox + dist * rx, oy + dist * ry, oz + dist * rz
    nx = b0 * normals[t, 0, 0] + b1 * normals[t, 1, 0] + b2 * normals[t, 2, 0]
    ny = b0 * normals[t, 0, 1] + b1 * normals[t, 1, 1] + b2 * normals[t, 2, 1]
    nz = b0 * normals[t, 0, 2] + b1 * normals[t, 1, 2] + b2 * normals[t, 2, 2]
    r, g, b = surface_color(material[t], u, v, hx, hy, hz, nx, ny, nz, rx, ry, rz,
                            mat_i, mat_f, texels, light_f, shading, ambient)
    return True, dist, r, g, b


@njit(cache=True, parallel=True)
def resolve_hits(surface_mode, hit, hx, hy, dist, rays, primary_rgb, tri, surface_ids,
                 n_objects, corners, uvs, normals, material, mat_i, mat_f, texels, light_f,
                 shading, ambient, refl, rgb):
    """rgb[y, x] += reflectance * colour at the hit, for every hit pixel; in place.

    A hit on a mirror pixel shows what the primary frame shows there ((1 - r) * base:
    one level of reflection, like rerender with max_depth = 1). In surface mode `dist`
    becomes the distance to the triangle's plane.
    """
    h, w = hit.shape
    for y in prange(h):
        for x in range(w):
            if hit[y, x] == 0:
                continue
            k = surface_ids[y, x] - n_objects
            sx = hx[y, x]
            sy = hy[y, x]
            c0 = primary_rgb[sy, sx, 0]
            c1 = primary_rgb[sy, sx, 1]
            c2 = primary_rgb[sy, sx, 2]
            t = tri[sy, sx]
            if surface_mode and t >= 0 and surface_ids[sy, sx] < n_objects:
                r = rays[y, x]
                ok, d, a0, a1, a2 = _surface_hit(t, r[0], r[1], r[2], r[3], r[4], r[5],
                                                 corners, uvs, normals, material, mat_i,
                                                 mat_f, texels, light_f, shading, ambient)
                if ok:
                    c0, c1, c2 = a0, a1, a2
                    dist[y, x] = d
            rgb[y, x, 0] += refl[k, 0] * c0
            rgb[y, x, 1] += refl[k, 1] * c1
            rgb[y, x, 2] += refl[k, 2] * c2


# confidence fades (fractions): screen border band, grazing n.v, camera-facing rays
EDGE_FADE = 0.1
GRAZING_FADE = 0.1


@njit(cache=True, parallel=True)
def confidence(hit, hx, hy, gap, rays, thickness, out):
    """Per hit pixel, the product of four fades in [0, 1] (0 on misses):
    the hit's distance to the screen border over EDGE_FADE of the smaller side; n.v over
    GRAZING_FADE (grazing rays); 1 - (eye-space direction toward the camera, r.z > 0) for
    camera-facing rays; 1 - |gap| / thickness (the depth gap at the hit)."""
    h, w = hit.shape
    band = EDGE_FADE * min(w, h)
    for y in prange(h):
        for x in range(w):
            if hit[y, x] == 0:
                out[y, x] = 0.0
                continue
            px = hx[y, x] + 0.5
            py = hy[y, x] + 0.5
            edge = min(min(px, w - px), min(py, h - py)) / band
            r = rays[y, x]
            graze = r[12] / GRAZING_FADE
            facing = 1.0 - max(r[11], 0.0)
            g = 1.0 - abs(gap[y, x]) / thickness if thickness > 0.0 else 1.0
            c = min(edge, 1.0) * min(graze, 1.0) * facing * max(g, 0.0)
            out[y, x] = min(max(c, 0.0), 1.0)



