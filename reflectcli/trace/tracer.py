"""Wavefront Whitted tracing of one frame: primary rays, then one batch per mirror bounce.

A ray's color accumulates along its path: at an object, weight * shade; at a mirror,
weight * (1 - r) * base, and the weight becomes weight * r for the reflected ray; on a miss,
weight * background. A mirror met after `max_depth` bounces adds only (1 - r) * base (its
reflection is not followed), so max_depth = 0 draws mirrors as their base color.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numba
import numpy as np
from numba import njit, prange

from ..camera import Camera
from ..frame import Frame
from ..scene.types import (
    CYLINDER_AXIS,
    CYLINDER_ORIGIN,
    MIRROR_TIE,
    PLANAR,
    PLANE_NORMAL,
    SPHERE,
    SPHERE_CENTER,
    UNLIT,
    Geometry,
    Scene,
)
from ..shading import material_albedo, surface_color
from .analytic import intersect_analytic, quad_edges
from .embree import TriangleScene
from .rays import primary_rays

_FAR_AWAY = np.float32(1e30)


class TraceBuffers:
    """Work arrays of the tracer kept across frames, by name: a frame's fresh arrays cost more
    in first-touch page faults than the tracing they hold (a 640x480 frame: about 16 of
    48 ms, 1 thread). Only the frame's own outputs (rgb, depth, ids) are new every frame."""

    def __init__(self) -> None:
        self._arrays: dict[str, np.ndarray] = {}
        self._edges: tuple[np.ndarray, np.ndarray] | None = None  # (mirror params, edges)

    def quad_edges(self, kind: np.ndarray, params: np.ndarray) -> np.ndarray:
        """analytic.quad_edges of the scene's mirrors, made once (the mirrors' parameters
        are the scene's: the same array every frame)."""
        if self._edges is None or self._edges[0] is not params:
            self._edges = (params, quad_edges(kind, params))
        return self._edges[1]

    def identity(self, n: int) -> np.ndarray:
        """0 .. n-1 (int64), kept: the primary rays' slots (read, never written)."""
        a = self._arrays.get("identity")
        if a is None or a.shape[0] != n:
            a = self._arrays["identity"] = np.arange(n, dtype=np.int64)
        return a

    def get(self, name: str, n: int, dtype, width: int = 0) -> np.ndarray:
        """The first n rows of buffer `name` ((n,) or (n, width)), grown when too small;
        contents are whatever the last frame left."""
        a = self._arrays.get(name)
        shape = (n, width) if width else (n,)
        if a is None or a.shape[0] < n or a.shape[1:] != shape[1:] or a.dtype != dtype:
            a = self._arrays[name] = np.empty(shape, dtype)
        return a[:n]


@dataclass
class Accelerators:
    """Embree scenes for one geometry state: objects, and mesh mirrors' triangles."""

    key: tuple
    objects: TriangleScene
    mirrors: TriangleScene
    mirror_corners: np.ndarray  # (Tm, 3, 3) mesh mirror triangles, in Embree's order
    mirror_normals: np.ndarray
    mirror_surface: np.ndarray
    buffers: TraceBuffers = field(default_factory=TraceBuffers)

    @property
    def build_seconds(self) -> float:
        return self.objects.build_seconds + self.mirrors.build_seconds


def build_accelerators(geometry: Geometry) -> Accelerators:
    m = geometry.mirror_tris
    exact = geometry.mirror_exact
    corners = np.ascontiguousarray(m.corners[exact])
    return Accelerators(
        geometry.key,
        TriangleScene(geometry.objects.corners),
        TriangleScene(corners),
        corners,
        np.ascontiguousarray(m.normals[exact]),
        np.ascontiguousarray(m.surface[exact]),
    )


def trace_frame(
    scene: Scene,
    geometry: Geometry,
    accel: Accelerators,
    camera: Camera,
    max_depth: int,
    samples: int = 1,
    threads: int = 1,
) -> Frame:
    """Ray trace one frame; `samples` x `samples` rays per pixel on a regular grid.

    The kernels' parallel loops hand out CHUNK rays at a time to whichever thread is free
    (not one fixed share per thread): on a busy machine a thread that loses its core no
    longer holds the others up. Every ray writes only its own outputs, so results do not
    depend on who traced what."""
    with numba.parallel_chunksize(CHUNK):
        return _trace_frame(scene, geometry, accel, camera, max_depth, samples, threads)


CHUNK = 2048  # rays per parallel work item


def _trace_frame(
    scene: Scene,
    geometry: Geometry,
    accel: Accelerators,
    camera: Camera,
    max_depth: int,
    samples: int = 1,
    threads: int = 1,
) -> Frame:
    timings: dict[str, float] = {"intersect": 0.0, "shade": 0.0}
    start = time.perf_counter()
    buffers = accel.buffers
    h, w = camera.height, camera.width
    spp = samples * samples
    n = h * w * spp
    # eye-space primary rays: start on the near plane, stop at the far plane (t = depth - near)
    origins, directions = primary_rays(camera, samples, out=(
        buffers.get("primary_o", n, np.float32, 3), buffers.get("primary_d", n, np.float32, 3)))
    tfar = buffers.get("tfar", n, np.float32)
    tfar.fill(camera.far - camera.near)
    slot = buffers.identity(n)  # the first wave reads neither slots nor weights: ones
    weight = buffers.get("weight", n, np.float32, 3)
    color = np.empty((n, 3), np.float32)  # the frame's rgb: new every frame, the first wave
    # writes every row
    depth = surface = None  # the primary wave's (bounce 0 always runs)
    reflected_hit = np.zeros(n, np.float32)  # first reflected ray hit geometry
    timings["primary_rays"] = time.perf_counter() - start
    rays = 0
    for bounce in range(max_depth + 1):
        if origins.shape[0] == 0:
            break
        rays += origins.shape[0]
        hit_t, hit_surface, alive, next_o, next_d, next_w = _wave(
            scene,
            geometry,
            accel,
            origins,
            directions,
            tfar,
            weight,
            slot,
            color,
            bounce < max_depth,
            threads,
            timings,
            first=bounce == 0,
        )
        if bounce == 0:
            depth = np.where(hit_surface >= 0, hit_t + np.float32(camera.near), np.inf)
            surface = hit_surface.copy()  # a buffer of the next frame's: the frame's own copy
        elif bounce == 1:
            reflected_hit[slot[hit_surface >= 0]] = 1.0
        # the rays that go on, in order, into the buffers of the next bounce's rays
        m = int(np.count_nonzero(alive))
        origins = buffers.get("ray_o", m, np.float32, 3)
        directions = buffers.get("ray_d", m, np.float32, 3)
        weight = buffers.get("ray_w", m, np.float32, 3)
        slot_in = slot
        slot = buffers.get("ray_slot_" + "ab"[bounce % 2], m, np.int64)
        _compact(alive, next_o, next_d, next_w, slot_in, origins, directions, weight, slot)
        tfar = buffers.get("tfar_bounce", m, np.float32)
        tfar.fill(_FAR_AWAY)
    if depth is None:  # no rays at all
        depth, surface = np.full(n, np.inf, np.float32), np.full(n, -1, np.int32)
    if spp == 1:  # the mean of one sample is the sample (bit for bit): no float64 pass
        rgb = color.reshape(h, w, 3)
        reflected_hit = reflected_hit.reshape(h, w)
    else:
        rgb = color.reshape(h, w, spp, 3).mean(axis=2, dtype=np.float64).astype(np.float32)
        reflected_hit = reflected_hit.reshape(h, w, spp).mean(axis=2).astype(np.float32)
    if spp > 1:  # Z, A and ids come from the pixel-center ray, traced once more
        o, d = primary_rays(camera, 1)
        m = d.shape[0]
        hit_t, surface, *_ = _wave(
            scene,
            geometry,
            accel,
            o,
            d,
            np.full(m, camera.far - camera.near, np.float32),
            np.ones((m, 3), np.float32),
            np.arange(m, dtype=np.int64),
            np.zeros((m, 3), np.float32),
            False,
            threads,
            timings,
        )
        surface = surface.copy()  # a buffer: the frame's own copy
        depth = np.where(surface >= 0, hit_t + np.float32(camera.near), np.inf)
        rays += m
    depth, surface = depth.reshape(h, w), surface.reshape(h, w)
    timings["trace"] = time.perf_counter() - start
    return Frame(
        rgb=rgb,
        depth=depth.astype(np.float32, copy=False),
        surface=surface.astype(np.int32, copy=False),
        mirror_mask=surface >= scene.n_objects,
        # what a mirror pixel's reflection should show: 1 where its reflected ray meets
        # geometry (an object or another mirror), 0 where it leaves for the background (the
        # fraction of samples that do, with supersampling); techniques' holes count against it
        extra={"reflected_hit": reflected_hit} if max_depth >= 1 else {},
        timings=timings,
        stats={"rays": int(rays)},
    )


def _wave(
    scene, geometry, accel, origins, directions, tfar, weight, slot, color, follow, threads,
    timings, first=False,
):
    """Intersect one batch of rays, shade their hits into color, emit reflected rays."""
    t0 = time.perf_counter()
    count = origins.shape[0]
    b = accel.buffers

    def hits(name):
        return (b.get(name + "_t", count, np.float32), b.get(name + "_prim", count, np.int32),
                b.get(name + "_u", count, np.float32), b.get(name + "_v", count, np.float32))

    t_o, p_o, u_o, v_o = accel.objects.intersect(origins, directions, tfar, threads,
                                                 out=hits("objects"))
    t_m, p_m, u_m, v_m = accel.mirrors.intersect(origins, directions, tfar, threads,
                                                 out=hits("mirrors"))
    t_a, k_a = intersect_analytic(
        origins, directions, tfar, scene.mirrors.kind, scene.mirrors.params, 0.0,
        out=(b.get("analytic_t", count, np.float32), b.get("analytic_k", count, np.int32)),
        edges=b.quad_edges(scene.mirrors.kind, scene.mirrors.params),
    )
    t1 = time.perf_counter()
    hit_t = b.get("hit_t", count, np.float32)
    hit_surface = b.get("hit_surface", count, np.int32)
    alive = b.get("alive", count, np.bool_)
    alive.fill(False)
    next_o = b.get("next_o", count, np.float32, 3)
    next_d = b.get("next_d", count, np.float32, 3)
    next_w = b.get("next_w", count, np.float32, 3)
    o, m = geometry.objects, scene.mirrors
    _resolve(
        origins,
        directions,
        weight,
        slot,
        t_o,
        p_o,
        u_o,
        v_o,
        t_m,
        p_m,
        u_m,
        v_m,
        t_a,
        k_a,
        o.corners,
        o.uvs,
        o.normals,
        o.material,
        o.surface,
        accel.mirror_corners,
        accel.mirror_normals,
        accel.mirror_surface,
        m.kind,
        m.params,
        m.reflectance,
        m.base,
        scene.n_objects,
        scene.materials.mat_i,
        scene.materials.mat_f,
        scene.materials.texels,
        scene.lights.light_f,
        scene.shading,
        scene.ambient,
        scene.background,
        follow,
        color,
        hit_t,
        hit_surface,
        alive,
        next_o,
        next_d,
        next_w,
        first,
    )
    timings["intersect"] += t1 - t0
    timings["shade"] += time.perf_counter() - t1
    return hit_t, hit_surface, alive, next_o, next_d, next_w


@njit(cache=True)
def _compact(alive, next_o, next_d, next_w, slot, out_o, out_d, out_w, out_slot):
    """The rays that go on, in order: the rows of next_o, next_d, next_w and slot where
    `alive` is set, into the out arrays (as many rows as alive has set); np.compress of
    each in one pass."""
    j = 0
    for i in range(alive.shape[0]):
        if alive[i]:
            for c in range(3):
                out_o[j, c] = next_o[i, c]
                out_d[j, c] = next_d[i, c]
                out_w[j, c] = next_w[i, c]
            out_slot[j] = slot[i]
            j += 1
    return j


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


@njit(cache=True, parallel=True)
def _resolve(
    origins,
    dirs,
    weight,
    slot,
    t_o,
    p_o,
    u_o,
    v_o,
    t_m,
    p_m,
    u_m,
    v_m,
    t_a,
    k_a,
    corners,
    uvs,
    normals,
    material,
    surface,
    m_corners,
    m_normals,
    m_surface,
    m_kind,
    m_params,
    m_refl,
    m_base,
    n_objects,
    mat_i,
    mat_f,
    texels,
    light_f,
    shading,
    ambient,
    background,
    follow,
    color,
    hit_t,
    hit_surface,
    alive,
    next_o,
    next_d,
    next_w,
    first,
):
    """Shade each ray's nearest hit into color[slot] and emit its reflected ray if any.

    Inputs are float32; hit points and reflected directions are worked in float64
    (np.float64(), since numba's float() keeps a float32 a float32). `first`: the primary
    wave, whose weights are ones and slots the identity (neither array is read) and whose
    color rows are written rather than added to (the same numbers: 0 + x is x, 1 * x is x;
    `color` may then hold anything before)."""
    for i in prange(origins.shape[0]):
        if first:
            s = np.int64(i)
            w = (np.float32(1.0), np.float32(1.0), np.float32(1.0))
        else:
            s = slot[i]
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
            tri = p_o[i]
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
            tri = p_m[i]
            k = m_surface[tri] - n_objects
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
            k = k_a[i]
            p = m_params[k]
            px, py, pz = ox + t * dx, oy + t * dy, oz + t * dz
            if m_kind[k] == PLANAR:
                gx, gy, gz = p[PLANE_NORMAL], p[PLANE_NORMAL + 1], p[PLANE_NORMAL + 2]
            elif m_kind[k] == SPHERE:
                gx = px - p[SPHERE_CENTER]
                gy = py - p[SPHERE_CENTER + 1]
                gz = pz - p[SPHERE_CENTER + 2]
            else:  # CYLINDER: radial direction from the axis
                lx = px - p[CYLINDER_ORIGIN]
                ly = py - p[CYLINDER_ORIGIN + 1]
                lz = pz - p[CYLINDER_ORIGIN + 2]
                ax, ay, az = p[CYLINDER_AXIS], p[CYLINDER_AXIS + 1], p[CYLINDER_AXIS + 2]
                h = lx * ax + ly * ay + lz * az
                gx, gy, gz = lx - h * ax, ly - h * ay, lz - h * az
            nx, ny, nz = gx, gy, gz
        hit_t[i] = t
        hit_surface[i] = n_objects + k
        for c in range(3):
            _add(color, s, c, w[c] * (1.0 - m_refl[k, c]) * m_base[k, c], first)
        if not follow:
            continue
        # face both normals toward the incoming ray (mirrors are two-sided)
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
        next_o[i, 0], next_o[i, 1], next_o[i, 2] = px + step * rx, py + step * ry, pz + step * rz
        next_d[i, 0], next_d[i, 1], next_d[i, 2] = rx, ry, rz
        any_weight = False
        for c in range(3):
            next_w[i, c] = w[c] * m_refl[k, c]
            any_weight = any_weight or next_w[i, c] > 0.0
        alive[i] = any_weight
