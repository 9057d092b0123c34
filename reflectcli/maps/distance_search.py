"""Searching a reflected ray in a layered distance cube map (numba): a linear march, then
secant (regula falsi) refinement (Szirmay-Kalos et al. 2005; Umenhoffer, Patow and
Szirmay-Kalos, GPU Gems 3 ch. 17).

Map space: world axes with the capture point o at the origin. The ray starts at x = p - o
(p on the reflector) with unit direction r. Its points are parameterized homogeneously,

    u(t) = (1 - t) x + t a r,   l(t) = u(t) / (1 - t) = x + r a t / (1 - t),   t in [0, 1),

with a = max(|x|, a_min): u(t) is the direction of l(t) seen from o, and it moves linearly
in t, so on a cube face its projection moves linearly too (uniform steps in t are uniform
steps over the texels, as in the papers). For a stored surface the test function is

    g(t) = (u(t) . axis_f) q(u(t)) - (1 - t),      q = 1 / w (stored inverse eye depth),

which has the sign of |l(t)| - (distance to the stored surface along u(t)), and which is
exactly linear in t for a planar surface (q is linear in face coordinates there and is
interpolated bilinearly), so one secant step lands on the plane.

Linear march: samples t_i = t_end i / steps, i = 0..steps (t_end: the point at distance
`far`). A crossing between t_i and t_{i+1} is a layer k at t_{i+1} with g_k >= 0 whose
surface id is also in a layer j at t_i with g_j < 0 (the same surface, in front then behind:
a surface that changes layer index between samples is still followed), or a layer j at t_i
with g_j < 0 whose stored distance differs from layer k's by at most CREASE_SLOPE x distance
x the angle between the samples (two surfaces meeting at a crease, the floor and a wall); a
larger jump is a silhouette, where the ray passes behind an object's edge, not a crossing.
Samples where no surface is stored (open sky, or a one-texel crack between triangles) are
skipped: the next sample is compared with the last one that saw something. Of the
crossings in a step, the one with the smallest secant root wins. Refinement: `refine`
regula-falsi steps on that surface (found by id in the layers at each new point; at a crease
either of the two), keeping a bracket; with refine = 0 the hit is t_{i+1}
(the linear march alone). The colour is the bilinear colour of that surface's layer in the
direction u(t_hit). No crossing: a hole (the background colour).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

from ..parallel import claim_rows, counter
from ..reflection import reflected_ray
from .cube import cube_face_coords, image_sample

# two different surfaces meet (a crease) when their stored distances at neighbouring samples
# differ by at most this many times (distance x angle between the samples); more is a
# silhouette, where the ray passes behind an object's edge and does not cross it
CREASE_SLOPE = 4.0


@njit(cache=True)
def sample_layer(q, surface, bases, k, ux, uy, uz):
    """(face, su, sv, id, q) of direction u in layer k: the nearest texel's surface id, and
    1/w bilinear over the 2x2 texel block when all four are that surface (extrapolated
    linearly in the outer half-texel of a face, exact for planes), else the nearest texel's.
    `q`, `surface`: search_texels' (6, S, S, layers) arrays."""
    face, su, sv = cube_face_coords(bases, ux, uy, uz)
    sid, qv = _texels(q, surface, k, face, su, sv)
    return face, su, sv, sid, qv


@njit(cache=True)
def _texels(q, surface, k, face, su, sv):
    """sample_layer's (id, q) at a face position found once for every layer."""
    res = q.shape[1]
    fx = su * res
    fy = sv * res
    xn = min(max(int(fx), 0), res - 1)
    yn = min(max(int(fy), 0), res - 1)
    sid = surface[face, yn, xn, k]
    qv = q[face, yn, xn, k]
    if sid < 0:
        return sid, 0.0
    x0 = min(max(int(math.floor(fx - 0.5)), 0), res - 2)
    y0 = min(max(int(math.floor(fy - 0.5)), 0), res - 2)
    if (surface[face, y0, x0, k] == sid and surface[face, y0, x0 + 1, k] == sid
            and surface[face, y0 + 1, x0, k] == sid and surface[face, y0 + 1, x0 + 1, k] == sid):
        ax = fx - 0.5 - x0
        ay = fy - 0.5 - y0
        qv = ((1.0 - ax) * (1.0 - ay) * q[face, y0, x0, k]
              + ax * (1.0 - ay) * q[face, y0, x0 + 1, k]
              + (1.0 - ax) * ay * q[face, y0 + 1, x0, k]
              + ax * ay * q[face, y0 + 1, x0 + 1, k])
    return sid, qv


@njit(cache=True)
def _g_of(bases, face, ux, uy, uz, qv, t):
    fwd = ux * bases[face, 2, 0] + uy * bases[face, 2, 1] + uz * bases[face, 2, 2]
    return fwd * qv - (1.0 - t)


@njit(cache=True)
def _g_surface(q, surface, bases, sid_a, sid_b, ux, uy, uz, t):
    """(g, layer) of the first layer holding surface sid_a or sid_b in direction u (layer
    -1 if none)."""
    for k in range(q.shape[3]):
        face, su, sv, s, qv = sample_layer(q, surface, bases, k, ux, uy, uz)
        if s >= 0 and (s == sid_a or s == sid_b):  # noqa: SIM109 (numba)
            return _g_of(bases, face, ux, uy, uz, qv, t), k
    return 0.0, -1


@njit(cache=True)
def _distance(bases, face, ux, uy, uz, qv):
    """Distance from the capture point to the stored surface along u (inf if none)."""
    if qv <= 0.0:
        return np.inf
    fwd = ux * bases[face, 2, 0] + uy * bases[face, 2, 1] + uz * bases[face, 2, 2]
    return math.sqrt(ux * ux + uy * uy + uz * uz) / (fwd * qv)


@njit(cache=True)
def _point(xx, xy, xz, rx, ry, rz, a, t):
    return (1.0 - t) * xx + t * a * rx, (1.0 - t) * xy + t * a * ry, (1.0 - t) * xz + t * a * rz


@njit(cache=True)
def _angle(ax, ay, az, bx, by, bz):
    c = (ax * bx + ay * by + az * bz) / math.sqrt(
        (ax * ax + ay * ay + az * az) * (bx * bx + by * by + bz * bz))
    return math.acos(min(max(c, -1.0), 1.0))


@njit(cache=True)
def search_ray(xx, xy, xz, rx, ry, rz, a, t_end, q, surface, color, bases, steps, refine,
               bilinear, out, work):
    """Search one ray (x, r in map space); out[:3] = colour. Returns (hit, samples taken):
    hit = 0 for a hole (out untouched). `work`: _search_work's arrays, reused ray to ray."""
    layers = q.shape[3]
    ga, da, sa, gb, db, sb = work
    for k in range(layers):
        face, su, sv, s, qv = sample_layer(q, surface, bases, k, xx, xy, xz)
        sa[k] = s
        ga[k] = _g_of(bases, face, xx, xy, xz, qv, 0.0)
        da[k] = _distance(bases, face, xx, xy, xz, qv)
    t_prev = 0.0
    pax, pay, paz = xx, xy, xz
    taken = 1
    for i in range(1, steps + 1):
        t = t_end * i / steps
        ux, uy, uz = _point(xx, xy, xz, rx, ry, rz, a, t)
        taken += 1
        # the face position, forward component and length of u are every layer's
        face, su, sv = cube_face_coords(bases, ux, uy, uz)
        sb[0], qv = _texels(q, surface, 0, face, su, sv)
        if sb[0] < 0:  # nothing stored (open sky, or a crack between triangles): no test
            continue
        fwd = ux * bases[face, 2, 0] + uy * bases[face, 2, 1] + uz * bases[face, 2, 2]
        length = math.sqrt(ux * ux + uy * uy + uz * uz)
        for k in range(layers):
            if k > 0:
                sb[k], qv = _texels(q, surface, k, face, su, sv)
            gb[k] = fwd * qv - (1.0 - t)  # _g_of
            db[k] = np.inf if qv <= 0.0 else length / (fwd * qv)  # _distance
        step_angle = -1.0  # the angle between the samples, when a crease test needs it
        best_t = 2.0
        best_a = -1
        best_b = -1
        best_gb = 0.0
        best_ga = 0.0
        for k in range(layers):
            if sb[k] < 0 or gb[k] < 0.0:
                continue
            partner = -1
            for j in range(layers):  # the same surface, in front of the ray at t_prev
                if sa[j] == sb[k] and ga[j] < 0.0:
                    partner = j
                    break
            if partner < 0:  # or another surface meeting it (a crease), not a silhouette
                if step_angle < 0.0:
                    step_angle = _angle(pax, pay, paz, ux, uy, uz)
                for j in range(layers):
                    if sa[j] >= 0 and ga[j] < 0.0 and abs(da[j] - db[k]) <= (
                            CREASE_SLOPE * step_angle * max(da[j], db[k])):
                        partner = j
                        break
            if partner >= 0:
                tc = t_prev + (t - t_prev) * ga[partner] / (ga[partner] - gb[k])
                if tc < best_t:
                    best_t, best_a, best_b = tc, sa[partner], sb[k]
                    best_ga, best_gb = ga[partner], gb[k]
        if best_b >= 0:
            lo, hi = t_prev, t
            g_lo, g_hi = best_ga, best_gb
            t_hit = t
            for _ in range(refine):
                tc = lo + (hi - lo) * g_lo / (g_lo - g_hi)
                cx, cy, cz = _point(xx, xy, xz, rx, ry, rz, a, tc)
                g, kk = _g_surface(q, surface, bases, best_b, best_a, cx, cy, cz, tc)
                taken += 1
                if kk < 0:
                    break
                t_hit = tc
                if g < 0.0:
                    lo, g_lo = tc, g
                elif g > 0.0:
                    hi, g_hi = tc, g
                else:
                    break
            hx, hy, hz = _point(xx, xy, xz, rx, ry, rz, a, t_hit)
            g, layer = _g_surface(q, surface, bases, best_b, best_a, hx, hy, hz, t_hit)
            layer = max(layer, 0)
            face, su, sv = cube_face_coords(bases, hx, hy, hz)
            c = image_sample(color[layer, face], su, sv, bilinear)
            for ch in range(3):
                out[ch] = c[ch]
            return 1, taken
        for k in range(layers):
            ga[k] = gb[k]
            da[k] = db[k]
            sa[k] = sb[k]
        t_prev = t
        pax, pay, paz = ux, uy, uz
    return 0, taken


def search_texels(q: np.ndarray, surface: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The (layers, 6, S, S) inverse depths and surface ids as the search reads them,
    (6, S, S, layers): a sample reads every layer at one texel, so a texel's layers share a
    cache line (read layer by layer from planes megabytes apart, the first read of each
    sample missed the cache: a fifth of a teapot-box search's time)."""
    return (np.ascontiguousarray(np.moveaxis(q, 0, -1)),
            np.ascontiguousarray(np.moveaxis(surface, 0, -1)))


@njit(cache=True)
def _search_work(layers):
    """A ray's per-layer test values at two samples (g, distance, id at t_prev; the same at
    t), allocated once per worker of _search_pixels and reused ray to ray, not per ray."""
    return (np.empty(layers), np.empty(layers), np.empty(layers, np.int64),
            np.empty(layers), np.empty(layers), np.empty(layers, np.int64))


def search_reflections(rgb, holes, steps_taken, buffers, surface_ids, surface, tris, kind,
                       params, reflectance, eye, capture, a_min, far, q, surf, color, bases,
                       steps, refine, bilinear, background):
    """On the pixels of `surface`: rgb += reflectance * searched colour (background in holes,
    marked in `holes`); steps_taken gets the samples per ray. In place. `q`, `surf`: the
    map's inverse depths and surface ids as search_texels lays them out."""
    _search_pixels(rgb, holes, steps_taken, buffers.triangle, buffers.b1, buffers.b2,
                   surface_ids, surface, tris.corners, tris.normals, kind,
                   np.asarray(params, np.float64), np.asarray(reflectance, np.float32),
                   np.asarray(eye, np.float64), np.asarray(capture, np.float64), float(a_min),
                   float(far), q, surf, color, bases, steps, refine, bilinear,
                   np.asarray(background, np.float32), numba.get_num_threads())


@njit(cache=True, parallel=True)
def _search_pixels(rgb, holes, steps_taken, tri, b1, b2, surface_ids, surface, corners, normals,
                   kind, p, refl, eye, capture, a_min, far, q, surf, color, bases, steps, refine,
                   bilinear, background, threads):
    """Each worker claims bands of rows until none is left: a pixel's result is its own
    whoever searches it. (Rows split evenly between 2 threads gave one 70% of a teapot-box
    frame's samples.)"""
    h, w = tri.shape
    claimed = counter()
    for _worker in prange(threads):
        out = np.empty(3, np.float32)
        work = _search_work(q.shape[3])
        y0, y1 = claim_rows(claimed, h)
        while y0 < y1:
            for y in range(y0, y1):
                _search_row(y, w, rgb, holes, steps_taken, tri, b1, b2, surface_ids, surface,
                            corners, normals, kind, p, refl, eye, capture, a_min, far, q, surf,
                            color, bases, steps, refine, bilinear, background, out, work)
            y0, y1 = claim_rows(claimed, h)


@njit(cache=True)
def _search_row(y, w, rgb, holes, steps_taken, tri, b1, b2, surface_ids, surface, corners,
                normals, kind, p, refl, eye, capture, a_min, far, q, surf, color, bases, steps,
                refine, bilinear, background, out, work):
    """The pixels of `surface` in row y."""
    for x in range(w):
        if surface_ids[y, x] != surface:
            continue
        px, py, pz, rx, ry, rz, _ = reflected_ray(tri[y, x], b1[y, x], b2[y, x], corners,
                                                  normals, kind, p, eye)
        inv = 1.0 / math.sqrt(rx * rx + ry * ry + rz * rz)
        rx, ry, rz = rx * inv, ry * inv, rz * inv
        xx, xy, xz = px - capture[0], py - capture[1], pz - capture[2]
        a = max(math.sqrt(xx * xx + xy * xy + xz * xz), a_min)
        t_end = far / (far + a)
        hit, taken = search_ray(xx, xy, xz, rx, ry, rz, a, t_end, q, surf, color, bases,
                                steps, refine, bilinear, out, work)
        steps_taken[y, x] = taken
        if hit == 0:
            holes[y, x] = 1.0
            for c in range(3):
                out[c] = background[c]
        for c in range(3):
            rgb[y, x, c] += refl[c] * out[c]
