"""Slow, obviously correct twins of the distance-map search kernels
(reflectcli/maps/distance_search.py), written from the spec in that module's docstring with
plain numpy vectors and an independent cube-face projection."""

from __future__ import annotations

import math

import numpy as np

from reflectcli.maps.distance_search import CREASE_SLOPE

AXES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
UPS = np.array([[0, 1, 0], [0, 1, 0], [0, 0, 1], [0, 0, -1], [0, 1, 0], [0, 1, 0]], float)


def face_uv(u):
    """(face, s, t): the face of u's major axis; s, t in [0, 1] (row 0 at the top)."""
    u = np.asarray(u, float)
    i = int(np.argmax(np.abs(u)))
    # ties resolve x before y before z, as the kernel does
    a = np.abs(u)
    if a[0] >= a[1] and a[0] >= a[2]:
        i = 0
    elif a[1] >= a[2]:
        i = 1
    else:
        i = 2
    face = 2 * i + (0 if u[i] > 0 else 1)
    axis = AXES[face]
    right = np.cross(UPS[face], -axis)
    right /= np.linalg.norm(right)
    up = np.cross(-axis, right)
    fwd = u @ axis
    return face, ((u @ right) / fwd + 1) / 2, (1 - (u @ up) / fwd) / 2


def layer_sample(q, surface, k, u):
    """(face, s, t, id, 1/w) of direction u in layer k, by the module's rule."""
    face, s, t = face_uv(u)
    res = q.shape[2]
    fx, fy = s * res, t * res
    xn, yn = min(max(int(fx), 0), res - 1), min(max(int(fy), 0), res - 1)
    sid = int(surface[k, face, yn, xn])
    if sid < 0:
        return face, s, t, sid, 0.0
    x0 = min(max(math.floor(fx - 0.5), 0), res - 2)
    y0 = min(max(math.floor(fy - 0.5), 0), res - 2)
    block = surface[k, face, y0:y0 + 2, x0:x0 + 2]
    if np.all(block == sid):
        ax, ay = fx - 0.5 - x0, fy - 0.5 - y0
        w = np.array([[(1 - ax) * (1 - ay), ax * (1 - ay)], [(1 - ax) * ay, ax * ay]])
        return face, s, t, sid, float((w * q[k, face, y0:y0 + 2, x0:x0 + 2]).sum())
    return face, s, t, sid, float(q[k, face, yn, xn])


def bilinear(image, s, t):
    res = image.shape[0]
    fx = min(max(s * res - 0.5, 0.0), res - 1.0)
    fy = min(max(t * res - 0.5, 0.0), res - 1.0)
    x0, y0 = min(int(fx), res - 2), min(int(fy), res - 2)
    ax, ay = fx - x0, fy - y0
    return ((1 - ax) * (1 - ay) * image[y0, x0] + ax * (1 - ay) * image[y0, x0 + 1]
            + (1 - ax) * ay * image[y0 + 1, x0] + ax * ay * image[y0 + 1, x0 + 1])


def naive_search(x, r, a, t_end, q, surface, color, steps, refine):
    """(hit, colour) of the ray x + r d in a layered map, by the module docstring's rule."""
    x, r = np.asarray(x, float), np.asarray(r, float)
    layers = q.shape[0]

    def u_at(t):
        return (1 - t) * x + t * a * r

    def look(t):
        u = u_at(t)
        rows = []
        for k in range(layers):
            face, _, _, sid, qv = layer_sample(q, surface, k, u)
            g = (u @ AXES[face]) * qv - (1 - t)
            dist = np.linalg.norm(u) / ((u @ AXES[face]) * qv) if qv > 0 else np.inf
            rows.append((sid, g, dist))
        return rows

    def angle(u, v):
        return math.acos(min(max(u @ v / (np.linalg.norm(u) * np.linalg.norm(v)), -1), 1))

    prev_t, prev = 0.0, look(0.0)
    for i in range(1, steps + 1):
        t = t_end * i / steps
        now = look(t)
        if now[0][0] < 0:
            continue
        step_angle = angle(u_at(prev_t), u_at(t))
        found = []
        for sid, g, dist in now:
            if sid < 0 or g < 0:
                continue
            partner = next((p for p in prev if p[0] == sid and p[1] < 0), None)
            if partner is None:
                partner = next((p for p in prev if p[0] >= 0 and p[1] < 0 and abs(p[2] - dist)
                                <= CREASE_SLOPE * step_angle * max(p[2], dist)), None)
            if partner is not None:
                tc = prev_t + (t - prev_t) * partner[1] / (partner[1] - g)
                found.append((tc, partner[0], sid, partner[1], g))
        if found:
            _, sid_a, sid_b, g_lo, g_hi = min(found, key=lambda f: f[0])

            def on_surface(tt, sid_a=sid_a, sid_b=sid_b):
                for k, (sid, g, _) in enumerate(look(tt)):
                    if sid >= 0 and sid in (sid_a, sid_b):
                        return g, k
                return 0.0, -1

            lo, hi, t_hit = prev_t, t, t
            for _ in range(refine):
                tc = lo + (hi - lo) * g_lo / (g_lo - g_hi)
                g, k = on_surface(tc)
                if k < 0:
                    break
                t_hit = tc
                if g < 0:
                    lo, g_lo = tc, g
                elif g > 0:
                    hi, g_hi = tc, g
                else:
                    break
            _, k = on_surface(t_hit)
            face, s, tt = face_uv(u_at(t_hit))
            return True, bilinear(color[max(k, 0), face], s, tt)
        prev_t, prev = t, now
    return False, None
