"""Slow, obviously correct twins of the screen-space kernels (reflectcli/screenspace/), and
the ground truth their hit masks are measured against. Plain Python and numpy, float64.
Each twin's docstring names the kernels it twins (tests/test_twins.py reads them)."""

from __future__ import annotations

import math

import numpy as np

EMPTY = 0xFFFFFFFFFFFFFFFF


def pyramid(depth: np.ndarray) -> list[np.ndarray]:
    """Twin of screenspace.hiz.build_pyramid: each level the minimum of 2x2 blocks, odd
    edges padded with +inf (the same as clamping: min(a, a) = a)."""
    levels = [depth.astype(np.float32)]
    while levels[-1].shape != (1, 1) and len(levels) < 16:
        d = levels[-1]
        h, w = d.shape
        p = np.full((h + h % 2, w + w % 2), np.inf, np.float32)
        p[:h, :w] = d
        levels.append(np.minimum.reduce([p[0::2, 0::2], p[1::2, 0::2], p[0::2, 1::2],
                                         p[1::2, 1::2]]))
    return levels


def pixel_walk(r, depth, surface_ids, own, thickness):
    """Twin of screenspace.hiz.march_hiz and march_hiz_all (and of its per-pixel test
    screenspace.hiz.pixel_overlap): visit every pixel the screen-space ray crosses, in order
    (Amanatides & Woo), from the pixel after the origin's; hit at the first whose segment of
    the ray has a depth range overlapping [s, s + thickness] (not on the ray's own surface).
    Returns (hit, x, y)."""
    h, w = depth.shape
    x0, y0, q0, x1, y1, q1 = (float(v) for v in r[14:20])
    dx, dy, dq = x1 - x0, y1 - y0, q1 - q0
    if max(abs(dx), abs(dy)) < 1e-6:
        return 0, -1, -1

    def exit_u(cx, cy):
        ux = ((cx + 1) - x0) / dx if dx > 0 else ((cx - x0) / dx if dx < 0 else math.inf)
        uy = ((cy + 1) - y0) / dy if dy > 0 else ((cy - y0) / dy if dy < 0 else math.inf)
        return min(ux, uy)

    eps = 1e-4 / max(abs(dx), abs(dy))
    u = exit_u(int(x0), int(y0)) + eps
    while u <= 1.0:
        x, y = x0 + dx * u, y0 + dy * u
        if not (0 <= x < w and 0 <= y < h):
            break
        cx, cy = int(x), int(y)
        u_out = min(exit_u(cx, cy), 1.0)
        da = 1.0 / (q0 + dq * u)
        qb = q0 + dq * u_out
        db = 1.0 / qb if qb > 0 else math.inf
        s = float(depth[cy, cx])
        if max(da, db) >= s and min(da, db) <= s + thickness and surface_ids[cy, cx] != own:
            return 1, cx, cy
        u = u_out + eps
    return 0, -1, -1


def dda_listing(r, depth, surface_ids, own, thickness, stride=1.0, max_steps=1 << 30):
    """Twin of screenspace.march.march_dda (march_all with DDA; no jitter, so
    screenspace.march.jitter_offset is tested apart): McGuire & Mara 2014's
    traceScreenSpaceRay listing, line by line in Python, in reflect's conventions (positive
    depth d = 1/k; their `rayZMax >= sceneZMax - zThickness` and `rayZMin <= sceneZMax` with
    negative z read `d_min <= s + thickness` and `d_max >= s` here). No jitter; the march
    starts one pixel past the origin. Returns (hit, x, y) of the step that hit (before the
    bisection, so stride = 1 only)."""
    h, w = depth.shape
    x0, y0, k0, x1, y1, k1 = (float(v) for v in r[14:20])
    if (x1 - x0) ** 2 + (y1 - y0) ** 2 < 1e-4:
        x1 += 0.01
    delta = [x1 - x0, y1 - y0]
    permute = abs(delta[0]) < abs(delta[1])
    p0, p1 = [x0, y0], [x1, y1]
    if permute:
        delta.reverse()
        p0.reverse()
        p1.reverse()
    step_dir = math.copysign(1.0, delta[0])
    inv_dx = step_dir / delta[0]
    dk = (k1 - k0) * inv_dx * stride
    dp = [step_dir * stride, delta[1] * inv_dx * stride]
    end = abs(delta[0])
    pos = 1.0  # pixels along the major axis from the origin
    p = [p0[0] + step_dir * pos, p0[1] + delta[1] * inv_dx * pos]
    k = k0 + (k1 - k0) * inv_dx * pos
    prev_zmax = 1.0 / k0
    steps = 0
    while pos <= end and steps < max_steps:
        steps += 1
        zmin = prev_zmax
        kh = k + 0.5 * dk
        zmax = 1.0 / kh if kh > 0 else math.inf
        prev_zmax = zmax
        zmin, zmax = min(zmin, zmax), max(zmin, zmax)
        hx, hy = (p[1], p[0]) if permute else (p[0], p[1])
        if not (0 <= hx < w and 0 <= hy < h):
            break
        cx, cy = int(hx), int(hy)
        s = float(depth[cy, cx])
        if zmax >= s and zmin <= s + thickness and surface_ids[cy, cx] != own:
            return 1, cx, cy
        p = [p[0] + dp[0], p[1] + dp[1]]
        k += dk
        pos += stride
    return 0, -1, -1


def linear_march(r, depth, surface_ids, own, thickness, steps, p00, p11):
    """Twin of screenspace.march.march_linear (march_all with LINEAR), without refinement: the
    first of `steps` equal eye-space steps whose projected pixel has its surface within [d -
    thickness, d]."""
    h, w = depth.shape
    o, dvec, length = np.asarray(r[6:9], float), np.asarray(r[9:12], float), float(r[13])
    for i in range(1, steps + 1):
        p = o + dvec * (length * i / steps)
        d = -p[2]
        sx = (p00 * p[0] / d + 1.0) * 0.5 * w
        sy = (1.0 - p11 * p[1] / d) * 0.5 * h
        if not (0 <= sx < w and 0 <= sy < h):
            break
        cx, cy = int(sx), int(sy)
        s = float(depth[cy, cx])
        if s <= d <= s + thickness and surface_ids[cy, cx] != own:
            return 1, i
    return 0, -1


def ppr_buffer(tri, b1, b2, surface_ids, n_objects, corners, plane, sid, clip_from_world):
    """Twin of screenspace.project.project_sources followed by scatter_min: a dict target
    index -> min key, from a Python loop."""
    h, w = tri.shape
    out: dict[int, int] = {}
    n, d = np.asarray(plane[:3], float), float(plane[3])
    for y in range(h):
        for x in range(w):
            s = surface_ids[y, x]
            if s < 0 or s >= n_objects:
                continue
            t = tri[y, x]
            c1, c2 = float(b1[y, x]), float(b2[y, x])
            c0 = 1.0 - c1 - c2
            a, b, c = (corners[t, i].astype(np.float64) for i in range(3))
            p = c0 * a + c1 * b + c2 * c  # the kernel's order of operations, so equal bits
            dist = n[0] * p[0] + n[1] * p[1] + n[2] * p[2] + d
            if not dist > 0:
                continue
            clip = clip_from_world @ np.append(p - 2 * dist * n, 1.0)
            if clip[3] <= 0 or not (-clip[3] <= clip[2] <= clip[3]):
                continue
            sx = (clip[0] / clip[3] + 1.0) * 0.5 * w
            sy = (1.0 - clip[1] / clip[3]) * 0.5 * h
            if not (0 <= sx < w and 0 <= sy < h):
                continue
            tx, ty = int(sx), int(sy)
            if surface_ids[ty, tx] != sid:
                continue
            bits = int(np.float32(dist).view(np.uint32))
            key = (bits << 32) | (y * w + x)
            target = ty * w + tx
            out[target] = min(out.get(target, EMPTY), key)
    return out


def truth_hits(rays, valid, geometry, depth, surface_ids, camera, rel_tol=0.02):
    """Where the ray tracer's reflected ray lands on a surface visible in the primary frame:
    (visible (H, W) bool, landed (H, W) bool). Rays of the mirror pixels (world origin and
    direction from the ray table) are traced against the objects with Embree; the hit is
    visible if it projects on screen within one pixel of a pixel of the same surface whose
    depth is within rel_tol of its own (a pixel's center sees another point of a slanted
    face than the exact landing point)."""
    from reflectcli.trace.embree import TriangleScene

    h, w = valid.shape
    idx = np.flatnonzero(valid.reshape(-1))
    table = rays.reshape(-1, rays.shape[-1])[idx]
    origins = table[:, 0:3] + 1e-4 * table[:, 3:6]
    scene = TriangleScene(geometry.objects.corners)
    t, prim, _, _ = scene.intersect(origins.astype(np.float32), table[:, 3:6].astype(np.float32),
                                    np.full(len(idx), 1e30, np.float32))
    landed = np.zeros(h * w, bool)
    visible = np.zeros(h * w, bool)
    view, proj = camera.view_matrix(), camera.projection_matrix()
    for j, i in enumerate(idx):
        if prim[j] < 0:
            continue
        landed[i] = True
        x = origins[j] + float(t[j]) * table[j, 3:6]
        e = view @ np.append(x, 1.0)
        dz = -e[2]
        if dz <= camera.near:
            continue
        c = proj @ e
        sx = (c[0] / c[3] + 1.0) * 0.5 * w
        sy = (1.0 - c[1] / c[3]) * 0.5 * h
        if not (0 <= sx < w and 0 <= sy < h):
            continue
        px, py = int(sx), int(sy)
        sid = geometry.objects.surface[prim[j]]
        ys = slice(max(py - 1, 0), py + 2)
        xs = slice(max(px - 1, 0), px + 2)
        near = (surface_ids[ys, xs] == sid) & (np.abs(depth[ys, xs] - dz) <= rel_tol * dz)
        visible[i] = bool(near.any())
    return visible.reshape(h, w), landed.reshape(h, w)


def fill_twin(buffer: np.ndarray, surface_ids: np.ndarray, n_objects: int) -> np.ndarray:
    """Twin of screenspace.project.fill_holes: an empty mirror pixel with reached pixels of the
    same mirror on both sides along a row, a column or a diagonal takes the smallest of
    those keys."""
    h, w = surface_ids.shape
    b = buffer.reshape(h, w)
    out = b.copy()
    for y in range(h):
        for x in range(w):
            s = surface_ids[y, x]
            if b[y, x] != EMPTY or s < n_objects:
                continue
            keys = []
            for dx, dy in ((1, 0), (0, 1), (1, 1), (1, -1)):
                pair = []
                for sgn in (1, -1):
                    xx, yy = x + sgn * dx, y + sgn * dy
                    if 0 <= xx < w and 0 <= yy < h and surface_ids[yy, xx] == s \
                            and b[yy, xx] != EMPTY:
                        pair.append(int(b[yy, xx]))
                if len(pair) == 2:
                    keys += pair
            if keys:
                out[y, x] = min(keys)
    return out.reshape(-1)


def screen_point(camera, p_eye):
    """Twin of screenspace.rays.to_screen: the eye-space point through the camera's own
    projection matrix, divided, to screen (x right, y down), and q = 1 / depth."""
    c = camera.projection_matrix() @ np.append(np.asarray(p_eye, float), 1.0)
    return ((c[0] / c[3] + 1.0) * 0.5 * camera.width, (1.0 - c[1] / c[3]) * 0.5 * camera.height,
            1.0 / -p_eye[2])


def ray_row(primary, scene, camera, y, x, max_distance):
    """Twin of screenspace.rays.mirror_rays for one mirror pixel: the row of the ray table,
    or None where no ray starts. Normals: the plane's, the sphere's radial, the cylinder's
    radial off its axis, else the interpolated vertex normal; turned toward the eye."""
    from reflectcli.scene.types import CYLINDER, PLANAR, SPHERE

    s = int(primary.frame.surface[y, x])
    if s < scene.n_objects:
        return None
    k = s - scene.n_objects
    t = primary.buffers.triangle[y, x]
    c1, c2 = float(primary.buffers.b1[y, x]), float(primary.buffers.b2[y, x])
    w = np.array([1.0 - c1 - c2, c1, c2])
    corners = primary.triangles.corners[t].astype(float)
    p = w @ corners
    prm = scene.mirrors.params[k]
    kind = scene.mirrors.kind[k]
    if kind == PLANAR:
        n = prm[:3].copy()
    elif kind == SPHERE:
        n = p - prm[:3]
    elif kind == CYLINDER:
        axis = prm[3:6]
        n = (p - prm[:3]) - ((p - prm[:3]) @ axis) * axis
    else:
        n = w @ primary.triangles.normals[t].astype(float)
    n = n / np.linalg.norm(n)
    v = camera.eye - p
    v = v / np.linalg.norm(v)
    if n @ v < 0:
        n = -n
    r = 2 * (n @ v) * n - v
    r = r / np.linalg.norm(r)
    view = camera.view_matrix()
    o_e = (view @ np.append(p, 1.0))[:3]
    d_e = view[:3, :3] @ r
    if -o_e[2] < camera.near:
        return None
    length = max_distance
    end = o_e + d_e * length
    if -end[2] < camera.near:  # stop on the near plane
        length = (-camera.near - o_e[2]) / d_e[2]
    if length <= 0:
        return None
    row = np.zeros(20)
    row[0:3], row[3:6], row[6:9], row[9:12] = p, r, o_e, d_e
    row[12], row[13] = n @ v, length
    row[14:17] = screen_point(camera, o_e)
    row[17:20] = screen_point(camera, o_e + d_e * length)
    return row


def distance_along(row, u, camera):
    """Twin of screenspace.rays.distance_at: bisection for the eye-space distance a along
    the ray whose screen x (or y) equals the screen segment's at parameter u."""
    o, d = row[6:9].astype(float), row[9:12].astype(float)
    axis = 0 if abs(row[17] - row[14]) >= abs(row[18] - row[15]) else 1
    target = row[14 + axis] + u * (row[17 + axis] - row[14 + axis])
    lo, hi = 0.0, float(row[13])
    rising = row[17 + axis] > row[14 + axis]
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        x = screen_point(camera, o + d * mid)[axis]
        if (x < target) == rising:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def resolve_pixel(surface_mode, row, hx, hy, primary_rgb, tri, surface_ids, n_objects, tris,
                  scene):
    """Twin of screenspace.resolve.resolve_hits for one hit: (colour, distance or None).
    pixel mode, or a background / mirror hit pixel: the primary colour there. surface mode:
    the ray meets the plane of the hit pixel's triangle (solved as a 3x3 system), whose
    barycentrics give uv and normal, shaded by the shading twin."""
    import naive

    color = primary_rgb[hy, hx].astype(float)
    t = tri[hy, hx]
    if not surface_mode or t < 0 or surface_ids[hy, hx] >= n_objects:
        return color, None
    a, b, c = tris.corners[t].astype(float)
    o, r = row[0:3].astype(float), row[3:6].astype(float)
    m = np.column_stack([-r, b - a, c - a])
    if abs(np.linalg.det(m)) < 1e-12:
        return color, None
    dist, b1, b2 = np.linalg.solve(m, o - a)
    if dist <= 0:
        return color, None
    w = np.array([1 - b1 - b2, b1, b2])
    uv = w @ tris.uvs[t].astype(float)
    n = w @ tris.normals[t].astype(float)
    hit = o + dist * r
    mats = scene.materials
    col = naive.surface_color(int(tris.material[t]), uv[0], uv[1], hit, n, r, mats.mat_i,
                              mats.mat_f, mats.texels, scene.lights.light_f, scene.shading,
                              scene.ambient)
    return np.asarray(col, float), dist


def confidence_of(hit, hx, hy, gap, row, thickness, w, h, edge=0.1, grazing=0.1):
    """Twin of screenspace.resolve.confidence for one pixel: 0 on a miss, else the product
    of the border fade (distance of the hit pixel's center to the nearest border over
    edge * min(w, h)), n.v over `grazing`, 1 - max(eye-space r.z, 0) and 1 - |gap| /
    thickness, each clamped to [0, 1]."""
    if not hit:
        return 0.0
    px, py = hx + 0.5, hy + 0.5
    fades = [min(px, w - px, py, h - py) / (edge * min(w, h)), row[12] / grazing,
             1.0 - max(row[11], 0.0), 1.0 - abs(gap) / thickness]
    return float(np.prod([min(max(f, 0.0), 1.0) for f in fades]))


def decode_key(key, w, row, tri, b1, b2, corners):
    """Twin of screenspace.project.decode for one target: (source x, source y, distance
    from the mirror point (row's origin) to the source pixel's surface point)."""
    src = int(key) & 0xFFFFFFFF
    sy, sx = divmod(src, w)
    t = tri[sy, sx]
    wts = np.array([1.0 - b1[sy, sx] - b2[sy, sx], b1[sy, sx], b2[sy, sx]], float)
    p = wts @ corners[t].astype(float)
    return sx, sy, float(np.linalg.norm(p - row[0:3].astype(float)))


def jitter_numbers(xs, ys):
    """Twin of screenspace.march.jitter_offset on arrays: the same integer hash in numpy
    int64 (which wraps like the kernel's machine integers), low 16 bits over 65536."""
    x = np.asarray(xs, np.int64)
    y = np.asarray(ys, np.int64)
    with np.errstate(over="ignore"):
        v = (x * np.int64(73856093)) ^ (y * np.int64(19349663))
        v = (v ^ (v >> np.int64(13))) * np.int64(1274126177)
        v = v ^ (v >> np.int64(16))
    return (v & np.int64(0xFFFF)) / 65536.0
