"""Explosion maps and the hidden map (Ofek & Rappoport, sec. 4), in numba.

Map space: a disk image of `res` x `res` texels whose circle of radius s/2 (s a little
smaller than res) holds every reflection direction. MapCoords of a unit direction
(x, y, z), expressed in a frame whose z axis points from the reflector's center to the eye:
    T = (s x / (2 sqrt(2 (z + 1))) + res / 2,  s y / (2 sqrt(2 (z + 1))) + res / 2).
The paper as transcribed has s x / sqrt(2 (z + 1)) + s / 2, whose circle has radius s (not
s/2) and does not fit the map: the factor 1/2 is restored here (x / sqrt(2 (z + 1)) spans
[-1, 1] on the unit sphere), and the circle is centered in the map.

Building (Figure 6): front-facing vertices (n . (E - V) >= 0) send a reflection ray to the
sphere (center C, radius d); the direction from C to the hit gives T. Front-facing triangles
are filled with their id. Profile triangles get their back-facing normals projected to be
orthogonal to the line of sight, then are filled the same way. ExtendMap adds, for each
profile triangle with two back-facing vertices, an extension quad from their T outward to
0.6 s from the center, filled (where still empty) with an extension id, so the circle is
covered. Lookup (MapToVirtualVertex): barycentric coordinates of a map point in the
triangle under it weight the triangle's vertices and normals into a plane of reflection;
for an extension quad, the position along its inner edge does. The point is mirrored across
that plane.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numba
import numpy as np
from numba import njit, prange

from ..fused import fma
from ..parallel import claim, counter
from ..raster.rasterize.buffers import scratch
from .mapfill import (
    _clear_unmarked,
    _fill_extensions,
    _fill_faces,
    _fill_holes,
    _holes,
    _ids_at_marked,
    _layer_triangles,
    _marked_box,
    _marked_texels,
    _nearest_filled,
)
from .mesh import IndexedMesh

EXTENSION_REACH = 0.6  # extension vertices end at this fraction of s from the map center

# numba's reference counting off (`_nrt=False`) in a loop's function that makes no array:
# each array a loop hands to an inlined helper, or view it takes, counts the array's
# references up and down, two atomic operations an item, which both threads contend for
# (the mask's map lookups: 12 -> 8 ms at 1 thread, 8.5 -> 4 ms at 2). The caller holds
# every array meanwhile.
_NO_COUNTS = {"_nrt": False}


@dataclass
class ExplosionMap:
    ids: np.ndarray  # (res, res) int32: face id, F + extension id, or -1
    coords: np.ndarray  # (V, 2) map coordinates of the vertices used (nan if unused)
    radius: float  # of the sphere the reflection rays were cut with
    filled_before_extension: int  # texels inside the circle filled by triangles alone (-1:
    # not counted, build_explosion_maps' lookups)
    empty_after_extension: int  # texels inside the circle ExtendMap left empty (then filled
    # with the nearest id, so that no lookup falls into a hole)
    core: np.ndarray  # (res, res) bool: texels filled by reflector triangles (reflected cells)


@dataclass
class ExplosionMaps:
    """The maps of one reflector (part) for one viewpoint, nearest sphere first: the paper's
    near and far maps, optionally with layers at radii in between."""

    mesh: IndexedMesh
    normals: np.ndarray  # (V, 3) normals with back-facing ones of profile triangles fixed
    front: np.ndarray  # (V,) bool
    frame: np.ndarray  # (3, 3) rows: map x, y, z (z from the center toward the eye)
    center: np.ndarray
    layers: list[ExplosionMap]
    extensions: np.ndarray  # (X, 3) int64: face, vertex i, vertex j
    res: int
    s: float
    # every layer's arrays at once (layer k's ids, coords and core are views of row k),
    # as the lookups take them
    all_ids: np.ndarray  # (L, res, res) int32
    all_coords: np.ndarray  # (L, V, 2)
    all_cores: np.ndarray  # (L, res, res) bool

    @property
    def near(self) -> ExplosionMap:
        return self.layers[0]

    @property
    def far(self) -> ExplosionMap:
        return self.layers[-1]


def ray_focus(mesh: IndexedMesh, eye: np.ndarray) -> np.ndarray:
    """The point nearest (least squares) to the lines of the front-facing vertices'
    reflection rays: where a concave reflector focuses them, or where a convex one seems to
    send them from. Seen from there, the direction to a scene point is close to the
    direction of the reflection ray that reaches it, at any distance. Falls back to the
    vertex mean when the rays are (nearly) parallel."""
    return ray_foci([mesh], eye)[0]


def ray_foci(meshes: list[IndexedMesh], eye: np.ndarray) -> list[np.ndarray]:
    """ray_focus of each mesh (a reflector's parts), their normal equations' condition
    numbers and solves each in one numpy call for all: the same bits (numpy's linalg
    works a stack matrix by matrix), without two calls a part (14 a mask frame)."""
    eye = np.asarray(eye, np.float64)
    sums = [_focus_sums(m.vertices, m.normals, eye) for m in meshes]
    return foci_from_sums(np.array([a for a, _, _ in sums]).reshape(-1, 3, 3),
                          np.array([b for _, b, _ in sums]).reshape(-1, 3),
                          np.array([f for _, _, f in sums], np.int64), meshes)


def foci_from_sums(a: np.ndarray, b: np.ndarray, front: np.ndarray,
                   meshes: list[IndexedMesh]) -> list[np.ndarray]:
    """ray_foci from each mesh's _focus_sums (a (M, 3, 3), b (M, 3), front counts (M,)):
    the normal equations of those with three or more front vertices solved where well
    posed, else the mesh's vertex mean."""
    out = [None] * len(meshes)
    posed = np.flatnonzero(front >= 3)
    if posed.size:
        posed_a = a[posed]
        # np.linalg.cond's answer to "not > 1e8", where the eigenvalues' closed form is sure
        # of it (a numpy call of 25-180 us a frame); numpy's where it is not
        sure = np.empty(posed.size, np.bool_)
        _surely_well_posed(posed_a, sure)
        cond = np.zeros(posed.size)
        if not sure.all():
            cond[~sure] = np.linalg.cond(posed_a[~sure])
        solved = posed[~(cond > 1e8)]
        if solved.size:
            x = np.linalg.solve(a[solved], b[solved][..., None])[..., 0]
            for i, focus in zip(solved.tolist(), x, strict=True):
                out[i] = focus
    return [m.vertices.mean(axis=0) if focus is None else focus
            for m, focus in zip(meshes, out, strict=True)]


@njit(cache=True)
def _focus_sums(v, n, eye):
    """(a, b, front count) of ray_focus's normal equations a x = b: over the front-facing
    vertices (n . (eye - v) >= 0), with r each one's unit eye ray reflected about its
    normal, a = sum of (I - r r^T), b = sum of (I - r r^T) v. The numbers numpy's
    whole-array version made (0.1-0.5 ms a part, 14 parts a mask frame), in its order of
    operations: a norm's squares summed in order, np.einsum's three-term dot products as
    (x0 y0 + x2 y2) + x1 y1, the sums over vertices in order. The twelve sums are kept in
    locals (in the arrays, each vertex's twelve additions waited on memory: 20 ns a vertex)."""
    a00 = a01 = a02 = a10 = a11 = a12 = a20 = a21 = a22 = 0.0
    b0 = b1 = b2 = 0.0
    front = 0
    for k in range(v.shape[0]):
        d0, d1, d2 = v[k, 0] - eye[0], v[k, 1] - eye[1], v[k, 2] - eye[2]
        length = math.sqrt((d0 * d0 + d1 * d1) + d2 * d2)
        d0, d1, d2 = d0 / length, d1 / length, d2 / length
        n0, n1, n2 = n[k, 0], n[k, 1], n[k, 2]
        if not (n0 * -d0 + n2 * -d2) + n1 * -d1 >= 0.0:
            continue
        front += 1
        twice = 2.0 * ((d0 * n0 + d2 * n2) + d1 * n1)
        r0, r1, r2 = d0 - twice * n0, d1 - twice * n1, d2 - twice * n2
        x0, x1, x2 = v[k, 0], v[k, 1], v[k, 2]
        # row i of I - r r^T: (delta_i0 - r_i r0, delta_i1 - r_i r1, delta_i2 - r_i r2)
        p0, p1, p2 = 1.0 - r0 * r0, 0.0 - r0 * r1, 0.0 - r0 * r2
        a00 += p0
        a01 += p1
        a02 += p2
        b0 += (p0 * x0 + p2 * x2) + p1 * x1
        p0, p1, p2 = 0.0 - r1 * r0, 1.0 - r1 * r1, 0.0 - r1 * r2
        a10 += p0
        a11 += p1
        a12 += p2
        b1 += (p0 * x0 + p2 * x2) + p1 * x1
        p0, p1, p2 = 0.0 - r2 * r0, 0.0 - r2 * r1, 1.0 - r2 * r2
        a20 += p0
        a21 += p1
        a22 += p2
        b2 += (p0 * x0 + p2 * x2) + p1 * x1
    a = np.empty((3, 3))
    a[0, 0], a[0, 1], a[0, 2] = a00, a01, a02
    a[1, 0], a[1, 1], a[1, 2] = a10, a11, a12
    a[2, 0], a[2, 1], a[2, 2] = a20, a21, a22
    b = np.empty(3)
    b[0], b[1], b[2] = b0, b1, b2
    return a, b, front


@njit(cache=True)
def _surely_well_posed(a, sure):
    """sure[j]: the symmetric 3x3 a[j] (a focus's normal equations: a sum of projectors,
    positive semi-definite) has a 2-norm condition number below 1e7 beyond doubt, so that
    np.linalg.cond (its singular values, here its eigenvalues, each within about 1e-15 of
    the largest) says it is not above 1e8. Its eigenvalues in closed form (the
    trigonometric solution of the characteristic cubic), with a margin of 1e-6 of the
    largest for their error (an arccos near +-1, at a double eigenvalue, loses half the
    digits: 1.5e-8); False where unsure, not finite, all zero or so small that the squares
    underflow (a focus's sums have a trace of twice their front vertices)."""
    for j in range(a.shape[0]):
        m = a[j]
        sure[j] = False
        q = (m[0, 0] + m[1, 1] + m[2, 2]) / 3.0
        p1 = m[0, 1] * m[0, 1] + m[0, 2] * m[0, 2] + m[1, 2] * m[1, 2]
        d0, d1, d2 = m[0, 0] - q, m[1, 1] - q, m[2, 2] - q
        p2 = d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * p1
        if not (np.isfinite(q) and np.isfinite(p2)) or not q > 1e-150:
            continue  # (below 1e-150 the squares may underflow: p2 says nothing)
        if p2 == 0.0:  # q times the identity
            sure[j] = True
            continue
        p = math.sqrt(p2 / 6.0)
        b00, b11, b22 = d0 / p, d1 / p, d2 / p
        b01, b02, b12 = m[0, 1] / p, m[0, 2] / p, m[1, 2] / p
        det = (b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02)
               + b02 * (b01 * b12 - b11 * b02))
        r = min(max(det / 2.0, -1.0), 1.0)
        phi = math.acos(r) / 3.0
        largest = q + 2.0 * p * math.cos(phi)
        least = q + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0)
        margin = 1e-6 * (abs(q) + 2.0 * p)
        sure[j] = least - margin > (largest + margin) * 1e-7


def map_frame(center: np.ndarray, eye: np.ndarray) -> np.ndarray:
    """Rows: the map's x, y, z axes (world), z the unit direction from `center` to the
    eye (_map_frames' for one centre, which a reflector's parts make together)."""
    frames = np.empty((1, 3, 3))
    _map_frames(np.asarray(center, np.float64).reshape(1, 3), np.asarray(eye, np.float64),
                frames)
    return frames[0]


@njit(cache=True)
def _map_frames(centers, eye, frames):
    """frames[j]: the map axes of centre centers[j] (rows x, y, z; z the unit direction to
    the eye, x the unit cross product of a helper axis (y, or x where z is within 0.9 of
    y) and z, y = z cross x). The numbers of numpy's whole-vector version (tests/naive.py
    map_frame: 15 us a part between a frame's kernels, 14 parts a mask frame) on this
    machine kind: np.linalg.norm of a 3-vector as sqrt(fma(x2, x2, fma(x1, x1, x0 x0)))
    (OpenBLAS's ddot), the cross products' products and differences as written."""
    for j in range(centers.shape[0]):
        z0, z1, z2 = eye[0] - centers[j, 0], eye[1] - centers[j, 1], eye[2] - centers[j, 2]
        length = math.sqrt(fma(z2, z2, fma(z1, z1, z0 * z0)))
        z0, z1, z2 = z0 / length, z1 / length, z2 / length
        h0, h1, h2 = (0.0, 1.0, 0.0) if abs(z1) < 0.9 else (1.0, 0.0, 0.0)
        x0, x1, x2 = h1 * z2 - h2 * z1, h2 * z0 - h0 * z2, h0 * z1 - h1 * z0
        length = math.sqrt(fma(x2, x2, fma(x1, x1, x0 * x0)))
        x0, x1, x2 = x0 / length, x1 / length, x2 / length
        frames[j, 0, 0], frames[j, 0, 1], frames[j, 0, 2] = x0, x1, x2
        frames[j, 1, 0] = z1 * x2 - z2 * x1
        frames[j, 1, 1] = z2 * x0 - z0 * x2
        frames[j, 1, 2] = z0 * x1 - z1 * x0
        frames[j, 2, 0], frames[j, 2, 1], frames[j, 2, 2] = z0, z1, z2


@njit(cache=True)
def map_coords(frame, res, s, dx, dy, dz):
    """T of a direction (need not be unit), in texel units."""
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    x = (frame[0, 0] * dx + frame[0, 1] * dy + frame[0, 2] * dz) / length
    y = (frame[1, 0] * dx + frame[1, 1] * dy + frame[1, 2] * dz) / length
    z = (frame[2, 0] * dx + frame[2, 1] * dy + frame[2, 2] * dz) / length
    m = 2.0 * math.sqrt(max(2.0 * (z + 1.0), 1e-24))
    return s * x / m + res / 2.0, s * y / m + res / 2.0


def build_explosion_maps(mesh: IndexedMesh, eye: np.ndarray, center: np.ndarray,
                         near_radius: float, far_radius: float, res: int,
                         layers: int = 2, boundary: np.ndarray | None = None,
                         lookups: np.ndarray | None = None,
                         flip_axis: np.ndarray | None = None) -> ExplosionMaps:
    """Maps at `layers` radii from near to far, spaced geometrically (2: the paper's pair).
    `boundary`: the mesh's boundary_edges, if already known (they depend on its faces
    alone, so a caller that keeps the mesh keeps them too). `lookups` (N, 3 world), if
    given: the only points virtual_vertices will look up in these maps (with `flip_axis`
    as it will be given there). Each layer is then right (ids and core as a whole build
    gives them) at the texels those points look up; elsewhere its ids and core are
    undefined (not cleared: nothing reads them), and its counts
    (filled_before_extension, empty_after_extension) are -1 where they were not
    counted."""
    return build_maps_together([map_setup(mesh, eye, center, near_radius, far_radius, res,
                                          layers, boundary, lookups, flip_axis)]).maps[0]


def layer_radii(near_radius, far_radius, layers: int) -> np.ndarray:
    """The layers' radii, spaced geometrically from near to far: (L,), or (P, L) for
    arrays of P parts' near and far radii, each part's row the bits of its own call: one
    numpy call for a reflector's parts (14 calls of 30-90 us a mask frame) where
    np.geomspace works element by element, which it does unless some part's step in
    log10 is zero (near == far: numpy's linspace then takes its other branch for every
    element), when each part gets a call of its own."""
    count = max(layers, 2)
    near = np.asarray(near_radius, np.float64)
    far = np.asarray(far_radius, np.float64)
    if not near.ndim:
        return np.geomspace(near, far, count)
    log_near, log_far = np.log10(near), np.log10(far)
    step = np.subtract(log_far, log_near) / (count - 1)
    if (step == 0).any():
        return np.array([np.geomspace(a, b, count) for a, b in zip(near, far, strict=True)])
    if not ((near > 0).all() and (far > 0).all() and np.isfinite(step).all()):
        return np.geomspace(near, far, count, axis=-1)
    # np.geomspace(near, far, count, axis=-1)'s steps for positive finite radii, without
    # its checks and conversions (160-210 us a mask frame, between kernels): linspace of
    # the logs as numpy makes it (y = arange * step + start, the last row the stop),
    # powers of ten, the ends set to near and far (its sign factors are all 1)
    y = np.arange(0, count, dtype=np.float64).reshape(-1, 1) * step
    y += log_near
    y[-1, ...] = log_far
    radii = np.power(10.0, y)
    radii[0] = near
    radii[-1] = far
    return np.moveaxis(radii, 0, -1)


@dataclass
class MapSetup:
    """One part's explosion maps before their texels (map_setup): what _build_layers
    takes for it."""

    mesh: IndexedMesh
    eye: np.ndarray  # float64 (3,)
    fixed: np.ndarray  # (V, 3) normals, back-facing ones of profile triangles fixed
    front: np.ndarray  # (V,) bool
    used: np.ndarray  # (V,) bool: vertices with map coordinates
    drawn: np.ndarray  # (D,) int64: faces drawn into the maps
    extensions: np.ndarray  # (X, 3) int64
    frame: np.ndarray  # (3, 3)
    center: np.ndarray  # float64 (3,)
    radii: np.ndarray  # (L,)
    res: int
    s: float
    lookups: np.ndarray | None  # (N, 3) float64: the points to be looked up, if known
    flip: np.ndarray  # (3,) their lookup's flip axis


def map_setup(mesh: IndexedMesh, eye: np.ndarray, center: np.ndarray, near_radius: float,
              far_radius: float, res: int, layers: int = 2,
              boundary: np.ndarray | None = None, lookups: np.ndarray | None = None,
              flip_axis: np.ndarray | None = None,
              radii: np.ndarray | None = None) -> MapSetup:
    """build_explosion_maps' per-vertex and per-face set-up, for build_maps_together.
    `radii`: layer_radii(near_radius, far_radius, layers), if already made."""
    v, n, f = mesh.vertices, mesh.normals, mesh.faces
    # an open reflector (a cap, a mask, a part of a split mesh) ends at boundary edges rather
    # than at a silhouette: they bound the reflected directions the same way
    if boundary is None:
        boundary = boundary_edges(f)
    eye = np.asarray(eye, np.float64)
    fixed, front, used, drawn, extensions = _setup_arrays(
        v, n, f, np.ascontiguousarray(boundary, np.int64).reshape(-1, 3), eye)
    frame = map_frame(center, eye)
    if radii is None:
        radii = layer_radii(near_radius, far_radius, layers)
    if lookups is not None:
        lookups = np.ascontiguousarray(lookups, np.float64)
    flip = np.zeros(3) if flip_axis is None else np.asarray(flip_axis, np.float64)
    return MapSetup(mesh, eye, fixed, front, used, drawn, extensions, frame,
                    np.asarray(center, np.float64), radii, res, res - 2.0, lookups, flip)


@njit(cache=True)
def _setup_arrays(v, n, faces, boundary, eye):
    """map_setup's arrays (Figure 6 of the paper), per vertex and face: front (V,) the
    vertices facing the eye (n . (eye - v) >= 0); fixed (V, 3) the normals, those of the
    back-facing vertices of profile faces (some vertices front-facing, some not) projected
    orthogonal to the line of sight and made unit; used (V,) front or so fixed; drawn (D,)
    the faces all front-facing or profile, ascending; extensions (X, 3): (face, i, j) for
    each profile face with two back-facing vertices (i, j in the face's order), then the
    boundary edges (face, i, j) of drawn faces between used vertices, in their order. The
    numbers of the whole-array numpy version (0.2 ms a part, 14 parts a mask frame) in its
    order of operations: np.einsum's three-term dot products as (x0 y0 + x2 y2) + x1 y1, a
    norm's squares summed in order."""
    count = v.shape[0]
    front = np.empty(count, np.bool_)
    for k in range(count):
        t0, t1, t2 = eye[0] - v[k, 0], eye[1] - v[k, 1], eye[2] - v[k, 2]
        front[k] = (n[k, 0] * t0 + n[k, 2] * t2) + n[k, 1] * t1 >= 0.0
    needs = np.zeros(count, np.bool_)
    n_faces = faces.shape[0]
    facing = np.empty(n_faces, np.int8)  # a face's front-facing vertices
    drawn_face = np.empty(n_faces, np.bool_)
    n_drawn = 0
    n_two_back = 0
    for i in range(n_faces):
        a, b, c = faces[i, 0], faces[i, 1], faces[i, 2]
        facing[i] = int(front[a]) + int(front[b]) + int(front[c])
        profile = 0 < facing[i] < 3
        if profile:
            needs[a] = needs[b] = needs[c] = True
            n_two_back += facing[i] == 1
        drawn_face[i] = profile or facing[i] == 3
        n_drawn += drawn_face[i]
    fixed = n.copy()
    used = np.empty(count, np.bool_)
    for k in range(count):
        needs[k] = needs[k] and not front[k]
        used[k] = front[k] or needs[k]
        if not needs[k]:
            continue
        t0, t1, t2 = eye[0] - v[k, 0], eye[1] - v[k, 1], eye[2] - v[k, 2]
        length = math.sqrt((t0 * t0 + t1 * t1) + t2 * t2)
        s0, s1, s2 = -t0 / length, -t1 / length, -t2 / length
        f0, f1, f2 = n[k, 0], n[k, 1], n[k, 2]
        dot = (f0 * s0 + f2 * s2) + f1 * s1
        p0, p1, p2 = f0 - dot * s0, f1 - dot * s1, f2 - dot * s2
        length = max(math.sqrt((p0 * p0 + p1 * p1) + p2 * p2), 1e-30)
        fixed[k, 0], fixed[k, 1], fixed[k, 2] = p0 / length, p1 / length, p2 / length
    drawn = np.empty(n_drawn, np.int64)
    j = 0
    for i in range(n_faces):
        if drawn_face[i]:
            drawn[j] = i
            j += 1
    open_edge = np.empty(boundary.shape[0], np.bool_)
    for e in range(boundary.shape[0]):
        open_edge[e] = (drawn_face[boundary[e, 0]] and used[boundary[e, 1]]
                        and used[boundary[e, 2]])
    extensions = np.empty((n_two_back + open_edge.sum(), 3), np.int64)
    j = 0
    for i in range(n_faces):
        if facing[i] != 1:
            continue
        extensions[j, 0] = i
        m = 1
        for corner in faces[i]:
            if not front[corner]:
                extensions[j, m] = corner
                m += 1
        j += 1
    for e in range(boundary.shape[0]):
        if open_edge[e]:
            extensions[j] = boundary[e]
            j += 1
    return fixed, front, used, drawn, extensions


@dataclass
class JoinedMaps:
    """Several parts' explosion maps (build_maps_together): the joined arrays, as
    _build_layers and _virtual_parts take them, and each part's ExplosionMaps (`maps`,
    views of them), made when first asked for: the parts' frames read the joined arrays
    alone (the 98 objects of the mask's maps took 0.3 ms a frame)."""

    setups: list[MapSetup]
    tally: np.ndarray  # (L, 2) each layer's counts (ExplosionMap's filled, empty)
    v: np.ndarray  # (V, 3): part p's vertices are rows starts[p, 0] .. starts[p + 1, 0]
    n: np.ndarray  # (V, 3) the maps' normals (fixed)
    faces: np.ndarray  # (F, 3), rows starts[p, 1] .. (vertex indices the part's own)
    extensions: np.ndarray  # (X, 3), rows starts[p, 3] ..
    starts: np.ndarray  # (P + 1, 4) int64
    layer_start: np.ndarray  # (P + 1,) int64: part p's layers
    radii: np.ndarray  # (L,)
    centers: np.ndarray  # (P, 3)
    frames: np.ndarray  # (P, 3, 3)
    ids: np.ndarray  # (L, res, res)
    coords: np.ndarray  # (sum over layers of their part's V, 2)
    coord_start: np.ndarray  # (L + 1,) int64
    core: np.ndarray  # (L, res, res)
    res: int
    s: float
    # with joined lookups: per point, where it is looked up (_lookup_at: tx, ty, distance;
    # texel x, y and the part's layer lo)
    at: np.ndarray | None = None  # (M, 3) float64
    cell: np.ndarray | None = None  # (M, 3) int64

    @cached_property
    def maps(self) -> list[ExplosionMaps]:
        """Each part's ExplosionMaps (its layers: views of the joined arrays)."""
        out = []
        res, s, tally = self.res, self.s, self.tally
        for p, u in enumerate(self.setups):
            k, layers = self.layer_start[p], len(u.radii)
            nv = len(u.mesh.vertices)
            c0 = self.coord_start[k]
            all_coords = self.coords[c0:c0 + layers * nv].reshape(layers, nv, 2)
            all_ids, all_cores = self.ids[k:k + layers], self.core[k:k + layers]
            maps = [ExplosionMap(all_ids[j], all_coords[j], radius, int(tally[k + j, 0]),
                                 int(tally[k + j, 1]), all_cores[j])
                    for j, radius in enumerate(u.radii)]
            out.append(ExplosionMaps(u.mesh, u.fixed, u.front, u.frame, u.center, maps,
                                     u.extensions, res, s, all_ids, all_coords, all_cores))
        return out


def build_maps_together(setups: list[MapSetup],
                        joined_lookups: tuple[np.ndarray, np.ndarray] | None = None,
                        ws=None, joined: tuple | None = None) -> JoinedMaps:
    """The explosion maps of several parts (map_setup: the same eye and resolution, all
    with lookups or all without), every layer of every part in one parallel region
    (_build_layers): each layer is what building its part alone makes. The mask's 14
    parts made 14 regions of 6 layers each, each region waiting for its slowest layer.
    `joined_lookups` (points (M, 3) float64, point_start (P + 1,)): the setups' lookups
    joined (part p's rows point_start[p] ..): their texels are then marked in one
    region for all parts (_mark_parts), and where each point is looked up kept
    (JoinedMaps.at, .cell) for virtual_vertices_together. `ws`: a RasterWorkspace whose
    arrays hold the maps (tens of megabytes a frame: fresh, their page faults cost more
    than the work in them); they are then valid until its next use. `joined`: the setups'
    (vertices, fixed normals, used, faces, drawn, extensions) already joined in their order
    (partsetup.parts_map_setups), else joined here."""
    res = setups[0].res
    s = res - 2.0
    whole = setups[0].lookups is None
    count = sum(len(u.radii) for u in setups)
    # per part: its rows of the joined vertex, face, drawn-face and extension arrays, and
    # its layers; per layer: its part, and its rows of the joined coordinates
    starts = np.zeros((len(setups) + 1, 4), np.int64)
    layer_start = np.zeros(len(setups) + 1, np.int64)
    layer_part = np.empty(count, np.int64)
    coord_start = np.zeros(count + 1, np.int64)
    k = 0
    for p, u in enumerate(setups):
        starts[p + 1] = starts[p] + (len(u.mesh.vertices), len(u.mesh.faces), len(u.drawn),
                                     len(u.extensions))
        layer_start[p + 1] = layer_start[p] + len(u.radii)
        for _ in u.radii:
            layer_part[k] = p
            coord_start[k + 1] = coord_start[k] + len(u.mesh.vertices)
            k += 1
    one = len(setups) == 1
    if joined is not None:
        v, n, used, faces, drawn, extensions = joined
    else:
        v = setups[0].mesh.vertices if one else np.concatenate([u.mesh.vertices
                                                                for u in setups])
        n = setups[0].fixed if one else np.concatenate([u.fixed for u in setups])
        used = setups[0].used if one else np.concatenate([u.used for u in setups])
        faces = setups[0].mesh.faces if one else np.concatenate([u.mesh.faces
                                                                 for u in setups])
        drawn = setups[0].drawn if one else np.concatenate([u.drawn for u in setups])
        extensions = (setups[0].extensions if one
                      else np.concatenate([u.extensions for u in setups]))
    centers = np.array([u.center for u in setups])
    frames = np.array([u.frame for u in setups])
    radii = np.concatenate([u.radii for u in setups])
    coords = scratch(ws, "maps_coords", (int(coord_start[-1]), 2), np.float64)
    ids = scratch(ws, "maps_ids", (count, res, res), np.int32)
    core = scratch(ws, "maps_core", (count, res, res), np.bool_)
    tally = np.zeros((count, 2), np.int64)
    # per layer, the texels looked up in it (layer k's: texels[texel_start[k]:texel_start[k
    # + 1]]), where known before its texels (`listed`; else _build_layer finds them)
    texel_start = np.zeros(count + 1, np.int64)
    texels = np.empty((0, 2), np.int64)
    listed = False
    at = cell = None
    if whole:
        needed = np.zeros((count, 0, 0), np.bool_)  # no restriction
    elif joined_lookups is not None:
        # all False on arrival; the texels marked here are cleared after (3.4 MB a mask
        # frame to clear whole, for 0.7% of it marked)
        needed = (np.zeros((count, res, res), np.bool_) if ws is None
                  else ws.zeroed("maps_needed", (count, res, res), np.bool_))
        points, point_start = joined_lookups
        at = scratch(ws, "maps_at", (points.shape[0], 3), np.float64)
        cell = scratch(ws, "maps_cell", (points.shape[0], 3), np.int64)
        _mark_parts(points, point_start, centers, np.array([u.flip for u in setups]), frames,
                    res, s, radii, layer_start, needed, at, cell)
        texels = scratch(ws, "maps_texels", (2 * points.shape[0], 2), np.int64)
        _lookup_texels(cell, point_start, layer_start, texel_start, texels)
        listed = True
    else:
        needed = np.zeros((count, res, res), np.bool_)
        k = 0
        for u in setups:
            layers = len(u.radii)
            _mark_lookups(u.lookups, u.center, u.flip, u.frame, res, s, u.radii,
                          needed[k:k + layers])
            k += layers
    _build_layers(v, n, used, faces, drawn, extensions, starts, setups[0].eye, centers,
                  frames, radii, layer_part, res, s, EXTENSION_REACH * s, coords,
                  coord_start, ids, core, tally, needed, listed, texel_start, texels,
                  numba.get_num_threads())
    if listed and ws is not None:
        _unmark(needed, texel_start, texels)
        ws.given_back_zeroed("maps_needed")
    return JoinedMaps(setups, tally, v, n, faces, extensions, starts, layer_start, radii,
                      centers, frames, ids, coords, coord_start, core, res, s, at, cell)


@njit(cache=True, parallel=True)
def _build_layers(v, n, used, faces, drawn, extensions, starts, eye, centers, frames, radii,
                  layer_part, res, s, reach_out, coords, coord_start, ids, core, tally,
                  needed, listed, texel_start, texels, threads):
    """Every layer's map at once, of one part or several (build_maps_together), layers
    claimed one at a time by whichever thread is free (parallel.py; each layer is work of
    its own, written to its own planes, so no value depends on which thread built it):
    vertex coordinates, faces, extension quads where still empty, then the nearest filled
    id in the texels left empty (skipped where no texel a lookup can reach is empty: the
    texels outside the map's disk then stay -1). Part p's vertices (v, n, used), faces,
    drawn faces and extensions (their indices the part's own) are rows starts[p, 0..3] to
    starts[p + 1, 0..3] of the joined arrays; layer k is part layer_part[k]'s, on the
    sphere of radius radii[k] about centers[p] (map frame frames[p]).
    coords[coord_start[k]:coord_start[k + 1]] (V, 2), ids[k], core[k] (res, res): layer
    k's; tally[k]: texels inside the map's circle filled by faces alone, and left empty
    after the extensions. needed (layers, res, res) bool: the texels lookups will read
    (build_explosion_maps' `lookups`), or (layers, 0, 0) for whole layers; if `listed`,
    texels[texel_start[k]:texel_start[k + 1]] are the marked texels of layer k
    (_lookup_texels' list), else each layer finds them.
    `threads`: numba.get_num_threads() of the caller."""
    half = s / 2.0
    # per texel, once for every layer: its center inside the map's circle, and its square
    # meeting the disk of map points (with rounding to spare: only those are looked up)
    circle = np.empty((res, res), np.bool_)
    reach = np.empty((res, res), np.bool_)
    for y in range(res):
        cy = y + 0.5 - res / 2.0
        gy = max(abs(cy) - 0.5, 0.0)  # the texel square's nearest point to the center
        for x in range(res):
            cx = x + 0.5 - res / 2.0
            gx = max(abs(cx) - 0.5, 0.0)
            circle[y, x] = cx ** 2 + cy ** 2 <= half ** 2
            reach[y, x] = gx * gx + gy * gy <= (half + 1e-6) ** 2
    count = radii.shape[0]
    claimed = counter()
    for _worker in prange(min(threads, count)):
        while True:
            k = claim(claimed)
            if k >= count:
                break
            p = layer_part[k]
            v0, v1 = starts[p, 0], starts[p + 1, 0]
            f0, f1 = starts[p, 1], starts[p + 1, 1]
            d0, d1 = starts[p, 2], starts[p + 1, 2]
            e0, e1 = starts[p, 3], starts[p + 1, 3]
            _build_layer(k, v[v0:v1], n[v0:v1], used[v0:v1], eye, centers[p], radii[k],
                         frames[p], res, s, faces[f0:f1], drawn[d0:d1], extensions[e0:e1],
                         f1 - f0, reach_out, circle, reach,
                         coords[coord_start[k]:coord_start[k + 1]], ids[k], core[k], tally,
                         needed[k], listed, texels[texel_start[k]:texel_start[k + 1]])


@njit(cache=True)
def _build_layer(k, v, n, used, eye, center, radius, frame, res, s, faces, drawn, extensions,
                 n_faces, reach_out, circle, reach, coords, layer, core, tally, needed,
                 listed, texels):
    """Layer k of _build_layers into coords, layer (ids) and core, its counts into
    tally[k]. The texel passes are branch-free (counts as sums of booleans) so that they
    vectorise; the nearest fill runs only where a lookup could land in an empty texel.
    With `needed` (res, res) marks, the ids and core of the marked texels alone are found,
    texel by texel (_ids_at_marked: the last face holding the texel, else the first
    extension quad, each by the fill's own tests); elsewhere ids and core are left as
    they were (not cleared), and the counts are -1 (not counted). If a marked texel is
    still empty, its nearest filled texel (by the whole map's rule) is found from the
    layer's triangles themselves (_fill_holes), nothing drawn; only where a layer fills
    nothing, or a hole lies where the whole map's fill would be skipped, is the whole
    layer made (drawing over texels already found changes nothing: a face's texel takes
    its last face again, and the extensions fill only texels no face holds)."""
    _vertex_coords(v, n, used, eye, center, radius, frame, res, s, coords)
    if needed.shape[0] > 0:
        tally[k, 0] = -1
        tally[k, 1] = -1
        # only the marked texels are read: the layer is not cleared first (17 MB a mask
        # frame); _ids_at_marked writes every marked texel's id and core
        # the marked texels and their box: from the lookups' list where known (a scan of
        # the layer's 40,000 marks took most of a layer's time where few are marked)
        if listed:
            y0, y1, x0, x1 = _texels_box(texels)
        else:
            y0, y1, x0, x1 = _marked_box(needed)
            texels = _marked_texels(needed, y0, y1, x0, x1)
        if y0 > y1:
            return  # nothing looked up here
        if _ids_at_marked(layer, core, needed, coords, faces, drawn, extensions, n_faces,
                          res / 2.0, reach_out, y0, y1, x0, x1, texels):
            return
        # a looked-up texel stays empty: each such hole takes the id of its nearest filled
        # texel, found from the triangles that could hold one (drawing boxes around the
        # holes, grown until each hole's nearest was sure, took 60% of these layers' time
        # on the mask: its holes lie 1 to 56 texels from theirs)
        holes, reached = _holes(layer, needed, reach, y0, y1, x0, x1)
        if reached:
            corners, value, rect = _layer_triangles(coords, faces, drawn, extensions,
                                                    n_faces, res / 2.0, reach_out, res)
            if _fill_holes(layer, texels, holes, corners, value, rect, drawn.shape[0]):
                return
        # the whole layer: the marked texels keep what _ids_at_marked found, which the
        # whole draw finds again; the others as cleared
        _clear_unmarked(layer, needed, 0, res - 1, 0, res - 1)
    else:
        layer[:, :] = -1
    _fill_faces(layer, coords, faces, drawn)
    filled = 0
    for y in range(res):
        for x in range(res):
            # a face's id (the extensions' come after them): the texels faces alone fill
            c = (layer[y, x] >= 0) & (layer[y, x] < n_faces)
            core[y, x] = c
            filled += c & circle[y, x]
    _fill_extensions(layer, coords, extensions, n_faces, res / 2.0, reach_out)
    left = 0
    unfilled = 0
    seen = 0  # empty texels a lookup can land in
    for y in range(res):
        for x in range(res):
            e = layer[y, x] < 0
            unfilled += e
            left += e & circle[y, x]
            seen += e & reach[y, x]
    tally[k, 0] = filled
    tally[k, 1] = left
    # every direction's map point lies in the disk of radius s / 2 (map_coords), so only
    # texels meeting it are ever looked up: with none of them empty, the fill (most of
    # a layer's time where the extensions closed the circle) would change no lookup
    if seen == 0 or unfilled == res * res:
        return
    empty = np.empty((res, res), np.bool_)
    for y in range(res):
        for x in range(res):
            empty[y, x] = layer[y, x] < 0
    rows = np.empty((res, res), np.int32)
    cols = np.empty((res, res), np.int32)
    _nearest_filled(empty, rows, cols)
    for y in range(res):
        for x in range(res):
            if empty[y, x]:
                layer[y, x] = layer[rows[y, x], cols[y, x]]


def boundary_edges(faces: np.ndarray) -> np.ndarray:
    """(B, 3) int64 (face, i, j) for every edge used by one face only, in face order."""
    seen: dict[tuple[int, int], list] = {}
    for fi, (a, b, c) in enumerate(faces):
        for i, j in ((a, b), (b, c), (c, a)):
            seen.setdefault((min(i, j), max(i, j)), []).append((fi, int(i), int(j)))
    return np.array([uses[0] for uses in seen.values() if len(uses) == 1],
                    np.int64).reshape(-1, 3)


@njit(cache=True, error_model="numpy")
def _vertex_coords(v, n, used, eye, center, radius, frame, res, s, coords):
    """coords (V, 2): each used vertex's map coordinates on the sphere (center, radius), NaN
    for the others. Every vertex is worked out, from its coordinates and normal copied
    into one array each, and the unused ones' answers replaced afterwards (numpy's error
    model: no check of a division), so that the loop has no branch and no stride and
    vectorises: its three square roots and six divisions a vertex made it 27 ns a vertex
    one at a time, 10 ns so (the same numbers; 31,000 vertices over the mask's layers)."""
    count = v.shape[0]
    soa = np.empty((8, count))  # vertex x, y, z, normal x, y, z; then map x, y
    for i in range(count):
        for c in range(3):
            soa[c, i] = v[i, c]
            soa[3 + c, i] = n[i, c]
    vx, vy, vz, nx, ny, nz, mx, my = (soa[0], soa[1], soa[2], soa[3], soa[4], soa[5],
                                      soa[6], soa[7])
    e0, e1, e2 = eye[0], eye[1], eye[2]
    c0, c1, c2 = center[0], center[1], center[2]
    f00, f01, f02 = frame[0, 0], frame[0, 1], frame[0, 2]
    f10, f11, f12 = frame[1, 0], frame[1, 1], frame[1, 2]
    f20, f21, f22 = frame[2, 0], frame[2, 1], frame[2, 2]
    for i in range(count):
        dx, dy, dz = vx[i] - e0, vy[i] - e1, vz[i] - e2
        inv = 1.0 / math.sqrt(dx * dx + dy * dy + dz * dz)
        dx, dy, dz = dx * inv, dy * inv, dz * inv
        dn = dx * nx[i] + dy * ny[i] + dz * nz[i]
        rx, ry, rz = dx - 2 * dn * nx[i], dy - 2 * dn * ny[i], dz - 2 * dn * nz[i]
        # the reflection ray leaves V (inside the sphere): its far root
        ox, oy, oz = vx[i] - c0, vy[i] - c1, vz[i] - c2
        b = ox * rx + oy * ry + oz * rz
        c = ox * ox + oy * oy + oz * oz - radius * radius
        t = -b + math.sqrt(max(b * b - c, 0.0))
        # map_coords of the hit's direction from the center
        hx, hy, hz = ox + t * rx, oy + t * ry, oz + t * rz
        length = math.sqrt(hx * hx + hy * hy + hz * hz)
        x = (f00 * hx + f01 * hy + f02 * hz) / length
        y = (f10 * hx + f11 * hy + f12 * hz) / length
        z = (f20 * hx + f21 * hy + f22 * hz) / length
        m = 2.0 * math.sqrt(max(2.0 * (z + 1.0), 1e-24))
        mx[i] = s * x / m + res / 2.0
        my[i] = s * y / m + res / 2.0
    for i in range(count):
        coords[i, 0] = mx[i] if used[i] else np.nan
        coords[i, 1] = my[i] if used[i] else np.nan


@njit(cache=True, inline="always")
def _lookup_at(q0, q1, q2, center, flip_axis, frame, res, s, radii):
    """(texel x, y, layer lo): where _virtual looks up point q, in maps lo and lo + 1."""
    dx, dy, dz = q0 - center[0], q1 - center[1], q2 - center[2]
    if dx * flip_axis[0] + dy * flip_axis[1] + dz * flip_axis[2] < 0.0:
        dx, dy, dz = -dx, -dy, -dz
    tx, ty = map_coords(frame, res, s, dx, dy, dz)
    dist = math.sqrt((q0 - center[0]) ** 2 + (q1 - center[1]) ** 2 + (q2 - center[2]) ** 2)
    lo = 0
    while lo < radii.shape[0] - 2 and dist > radii[lo + 1]:
        lo += 1
    cx = min(max(int(math.floor(tx)), 0), res - 1)
    cy = min(max(int(math.floor(ty)), 0), res - 1)
    return tx, ty, cx, cy, dist, lo


@njit(cache=True)
def _lookup_texels(cell, point_start, layer_start, texel_start, texels):
    """The texels _mark_parts marked in each layer k, from each point's cell (texel x, y
    and its part's layer lo; it marks lo and lo + 1): texels[texel_start[k]:texel_start[k +
    1]] (row, column) the texel of each point looking layer k up, in the points' order (a
    texel once per point: several may share it). texel_start (K + 1,), texels (2 M, 2) for
    M points. (Their boxes are found by each layer from its list, in the layers' parallel
    region: here, their minima and maxima updated point by point made a chain through
    memory, three times the time of the lists.)"""
    texel_start[:] = 0
    for p in range(point_start.shape[0] - 1):
        base = layer_start[p]
        for i in range(point_start[p], point_start[p + 1]):
            k = base + cell[i, 2]
            texel_start[k + 1] += 1
            texel_start[k + 2] += 1
    for k in range(texel_start.shape[0] - 1):
        texel_start[k + 1] += texel_start[k]
    at = texel_start[:-1].copy()  # where each layer's next texel goes
    for p in range(point_start.shape[0] - 1):
        base = layer_start[p]
        for i in range(point_start[p], point_start[p + 1]):
            k = base + cell[i, 2]
            texels[at[k], 0], texels[at[k], 1] = cell[i, 1], cell[i, 0]
            texels[at[k + 1], 0], texels[at[k + 1], 1] = cell[i, 1], cell[i, 0]
            at[k] += 1
            at[k + 1] += 1


@njit(cache=True)
def _unmark(needed, texel_start, texels):
    """needed[k] set False again at layer k's listed texels (_lookup_texels' lists: every
    texel _mark_parts marked)."""
    for k in range(texel_start.shape[0] - 1):
        for t in range(texel_start[k], texel_start[k + 1]):
            needed[k, texels[t, 0], texels[t, 1]] = False


@njit(cache=True)
def _texels_box(texels):
    """(y0, y1, x0, x1): the box of (T, 2) texels (row, column); y0 > y1 if none."""
    y0, y1, x0, x1 = 1 << 30, -1, 1 << 30, -1
    for t in range(texels.shape[0]):
        y0 = min(y0, texels[t, 0])
        y1 = max(y1, texels[t, 0])
        x0 = min(x0, texels[t, 1])
        x1 = max(x1, texels[t, 1])
    return y0, y1, x0, x1


@njit(cache=True, error_model="numpy")
def _mark_lookups(points, center, flip_axis, frame, res, s, radii, needed):
    """needed[lo], needed[lo + 1] set at the texel each point is looked up at (_virtual,
    whose numpy error model it shares: a point at the center gives NaN, clamped, not an
    error). One thread: about 13 ns a point (3x less than with Python's checks for zero
    divisors), less than a parallel loop's start on a busy machine."""
    for i in range(points.shape[0]):
        _, _, cx, cy, _, lo = _lookup_at(points[i, 0], points[i, 1], points[i, 2], center,
                                         flip_axis, frame, res, s, radii)
        needed[lo, cy, cx] = True
        needed[lo + 1, cy, cx] = True


@njit(cache=True, parallel=True, error_model="numpy")
def _mark_parts(points, point_start, centers, flips, frames, res, s, radii, layer_start,
                needed, at, cell):
    """_mark_lookups for several parts at once (part p's points rows point_start[p] ..,
    its layers layer_start[p] ..), in blocks of points, and each point's _lookup_at
    answer kept in at (tx, ty, distance) and cell (texel x, y, lo), which _virtual_parts
    then reads instead of finding it again. Two threads may mark one texel: both store
    True (a benign race; no value depends on which store lands)."""
    total = points.shape[0]
    for b in prange((total + 1023) // 1024):
        p = 0
        for i in range(b * 1024, min(total, (b + 1) * 1024)):
            while point_start[p + 1] <= i:
                p += 1
            k0, k1 = layer_start[p], layer_start[p + 1]
            tx, ty, cx, cy, dist, lo = _lookup_at(points[i, 0], points[i, 1], points[i, 2],
                                                  centers[p], flips[p], frames[p], res, s,
                                                  radii[k0:k1])
            needed[k0 + lo, cy, cx] = True
            needed[k0 + lo + 1, cy, cx] = True
            at[i, 0], at[i, 1], at[i, 2] = tx, ty, dist
            cell[i, 0], cell[i, 1], cell[i, 2] = cx, cy, lo


def virtual_vertices(maps: ExplosionMaps, points: np.ndarray, hidden_face: np.ndarray,
                     hidden_screen: np.ndarray, screen_coords: np.ndarray,
                     flip_axis: np.ndarray | None = None):
    """Figure 7 for many points: hidden points (hidden_face >= 0, at screen position
    hidden_screen) through the hidden map (the reflector's item buffer, whose triangles'
    screen positions are screen_coords); the others through the two maps whose spheres
    bracket the point (the near and far maps when there are two), blended by the inverse
    distances to those spheres. Returns (virtual points, flags: hidden, or outside every
    reflected cell (the unreflected region) - their virtual vertices only close polygons)."""
    out = np.empty(points.shape, np.float64)
    m = maps.mesh
    ids, coords, cores = maps.all_ids, maps.all_coords, maps.all_cores
    radii = np.array([layer.radius for layer in maps.layers])
    unreflected = np.zeros(points.shape[0], np.bool_)
    flip = np.zeros(3) if flip_axis is None else np.asarray(flip_axis, np.float64)
    _virtual(np.ascontiguousarray(points, np.float64), m.vertices, maps.normals, m.faces,
             maps.extensions, ids, np.ascontiguousarray(coords).reshape(-1, 2), radii,
             maps.center, flip, maps.frame, maps.res,
             maps.s, hidden_face, hidden_screen, screen_coords, cores, out, unreflected)
    return out, (hidden_face >= 0) | unreflected


@njit(cache=True, inline="always")
def _blend3(arr, a, b, c, wa, wb, wc):
    """wa arr[a] + wb arr[b] + wc arr[c] (rows of 3), as a tuple (no array per call)."""
    return (wa * arr[a, 0] + wb * arr[b, 0] + wc * arr[c, 0],
            wa * arr[a, 1] + wb * arr[b, 1] + wc * arr[c, 1],
            wa * arr[a, 2] + wb * arr[b, 2] + wc * arr[c, 2])


@njit(cache=True, inline="always")
def _unit_or_zero(nn, always):
    """nn / |nn| (if `always` or |nn| > 0; else nn as it is)."""
    length = math.sqrt(nn[0] ** 2 + nn[1] ** 2 + nn[2] ** 2)
    if always or length > 0.0:
        return nn[0] / length, nn[1] / length, nn[2] / length
    return nn


@njit(cache=True, inline="always")
def _plane_from_map(ids, coords, v, n, faces, extensions, tx, ty):
    """(plane point, unit normal) for map point T, or a zero normal if the texel is empty
    (tuples: the lookup runs per point and map, and arrays made per call cost more than
    the arithmetic)."""
    res = ids.shape[0]
    x = min(max(int(math.floor(tx)), 0), res - 1)
    y = min(max(int(math.floor(ty)), 0), res - 1)
    return _plane_of(ids[y, x], coords, 0, v, n, faces, extensions, tx, ty)


@njit(cache=True, inline="always")
def _plane_of(ident, coords, at, v, n, faces, extensions, tx, ty):
    """_plane_from_map for the texel's id `ident`, the map's vertex coordinates rows at ..
    of `coords` (so that the joined maps are read in place: a view made per point and map
    costs two atomic counts, which also wait on the lookups' loads)."""
    if ident < 0:
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    nf = faces.shape[0]
    if ident < nf:
        a, b, c = faces[ident, 0], faces[ident, 1], faces[ident, 2]
        ax, ay = coords[at + a, 0], coords[at + a, 1]
        bx, by = coords[at + b, 0], coords[at + b, 1]
        cx, cy = coords[at + c, 0], coords[at + c, 1]
        area = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
        if area == 0.0:
            wb = wc = 1.0 / 3.0
        else:
            wb = ((tx - ax) * (cy - ay) - (cx - ax) * (ty - ay)) / area
            wc = ((bx - ax) * (ty - ay) - (tx - ax) * (by - ay)) / area
        wa = 1.0 - wb - wc  # negative weights are fine (the paper says so)
        p = _blend3(v, a, b, c, wa, wb, wc)
        nn = _blend3(n, a, b, c, wa, wb, wc)
    else:
        e = ident - nf
        i, j = extensions[e, 1], extensions[e, 2]
        ex, ey = coords[at + j, 0] - coords[at + i, 0], coords[at + j, 1] - coords[at + i, 1]
        ll = ex * ex + ey * ey
        u = 0.5 if ll == 0.0 else ((tx - coords[at + i, 0]) * ex
                                   + (ty - coords[at + i, 1]) * ey) / ll
        u = min(max(u, 0.0), 1.0)
        p = ((1.0 - u) * v[i, 0] + u * v[j, 0], (1.0 - u) * v[i, 1] + u * v[j, 1],
             (1.0 - u) * v[i, 2] + u * v[j, 2])
        nn = ((1.0 - u) * n[i, 0] + u * n[j, 0], (1.0 - u) * n[i, 1] + u * n[j, 1],
              (1.0 - u) * n[i, 2] + u * n[j, 2])
    return p, _unit_or_zero(nn, False)


@njit(cache=True)
def _screen_plane(faces, f, screen, v, n, sx, sy):
    """(point, unit normal) interpolated over reflector triangle f at screen point (sx, sy)
    from its vertices' screen positions; a zero normal if the triangle is degenerate."""
    a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
    ax, ay, bx, by = screen[a, 0], screen[a, 1], screen[b, 0], screen[b, 1]
    cx, cy = screen[c, 0], screen[c, 1]
    area = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
    if area == 0.0:
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    wb = ((sx - ax) * (cy - ay) - (cx - ax) * (sy - ay)) / area
    wc = ((bx - ax) * (sy - ay) - (sx - ax) * (by - ay)) / area
    wa = 1.0 - wb - wc
    return _blend3(v, a, b, c, wa, wb, wc), _unit_or_zero(_blend3(n, a, b, c, wa, wb, wc),
                                                          True)


@njit(cache=True, inline="always")
def _mirror(q, p, nn):
    d = (q[0] - p[0]) * nn[0] + (q[1] - p[1]) * nn[1] + (q[2] - p[2]) * nn[2]
    return q[0] - 2 * d * nn[0], q[1] - 2 * d * nn[1], q[2] - 2 * d * nn[2]


@njit(cache=True, parallel=True)
def _virtual(points, v, n, faces, extensions, ids, flat, radii, center, flip_axis, frame,
             res, s, hidden_face, hidden_screen, screen, cores, out, unreflected):
    """virtual_vertices' loop (flat: the layers' vertex coordinates (L x V, 2), layer l's
    rows l V ..)."""
    nv = v.shape[0]
    for i in prange(points.shape[0]):
        h = hidden_face[i]
        if h >= 0 and _through_hidden(points, i, faces, h, screen, v, n, hidden_screen, out):
            continue
        # a point between a concave reflector and the focus of its rays is reached by a ray
        # still travelling toward the focus: look up the direction that ray is going in
        tx, ty, cx, cy, dist, lo = _lookup_at(points[i, 0], points[i, 1], points[i, 2],
                                              center, flip_axis, frame, res, s, radii)
        _through_maps(points, i, v, n, faces, extensions, ids, lo, flat, lo * nv,
                      (lo + 1) * nv, cores, tx, ty, cx, cy, dist, radii[lo], radii[lo + 1],
                      out, unreflected)


@njit(cache=True, inline="always")
def _through_hidden(points, i, faces, h, screen, v, n, hidden_screen, out):
    """Point i through the hidden map (its part face h in front of it, at screen position
    hidden_screen[i]: barycentrics in the reflector triangle on screen) into out[i]; False
    if the triangle is degenerate there (the point then goes through the maps)."""
    p, nn = _screen_plane(faces, h, screen, v, n, hidden_screen[i, 0], hidden_screen[i, 1])
    if nn[0] != 0.0 or nn[1] != 0.0 or nn[2] != 0.0:
        q = (points[i, 0], points[i, 1], points[i, 2])
        out[i, 0], out[i, 1], out[i, 2] = _mirror(q, p, nn)
        return True
    return False


@njit(cache=True, inline="always")
def _through_maps(points, i, v, n, faces, extensions, ids, k, coords, at_near, at_far, cores,
                  tx, ty, cx, cy, dist, r_near, r_far, out, unreflected):
    """Point i through the two maps bracketing it (_lookup_at's answer), layers k and k + 1
    of ids and cores (L, res, res), their vertex coordinates rows at_near .. and at_far ..
    of coords, into out[i] and unreflected[i]."""
    q = (points[i, 0], points[i, 1], points[i, 2])
    unreflected[i] = not (cores[k, cy, cx] and cores[k + 1, cy, cx])
    res = ids.shape[1]
    x = min(max(int(math.floor(tx)), 0), res - 1)
    y = min(max(int(math.floor(ty)), 0), res - 1)
    pn, nn_ = _plane_of(ids[k, y, x], coords, at_near, v, n, faces, extensions, tx, ty)
    pf, nf_ = _plane_of(ids[k + 1, y, x], coords, at_far, v, n, faces, extensions, tx, ty)
    has_near = nn_[0] ** 2 + nn_[1] ** 2 + nn_[2] ** 2 > 0
    has_far = nf_[0] ** 2 + nf_[1] ** 2 + nf_[2] ** 2 > 0
    wn = 1.0 / max(abs(dist - r_near), 1e-12) if has_near else 0.0
    wf = 1.0 / max(abs(dist - r_far), 1e-12) if has_far else 0.0
    if wn + wf == 0.0:
        out[i, 0], out[i, 1], out[i, 2] = q[0], q[1], q[2]
        return
    xn = _mirror(q, pn, nn_)
    xf = _mirror(q, pf, nf_)
    for c in range(3):
        out[i, c] = (wn * xn[c] + wf * xf[c]) / (wn + wf)


def virtual_vertices_together(joined: JoinedMaps, points: np.ndarray, point_start: np.ndarray,
                              hidden_face: np.ndarray, hidden_screen: np.ndarray,
                              screen_coords: list[np.ndarray],
                              ws=None) -> tuple[np.ndarray, np.ndarray]:
    """virtual_vertices for every part of `joined` at once (built with joined_lookups
    `points` (M, 3), part p's rows point_start[p] ..; with their hidden faces (M,) and
    screen positions `hidden_screen` (M, 2 or more: x, y first); the part's vertices on
    the screen screen_coords[p]), in one parallel region (_virtual_parts): (virtual (M, 3),
    flags (M,)), each part's rows what virtual_vertices gives it (`ws`: as
    build_maps_together's)."""
    counts = np.diff(point_start)
    chunk_start = np.zeros(len(counts) + 1, np.int64)
    chunk_start[1:] = np.cumsum((counts + _LOOKUP_CHUNK - 1) // _LOOKUP_CHUNK)
    total = points.shape[0]
    out = scratch(ws, "lookup_out", (total, 3), np.float64)
    unreflected = scratch(ws, "lookup_unreflected", (total,), np.bool_)
    unreflected.fill(False)
    _virtual_parts(np.ascontiguousarray(points, np.float64), point_start, chunk_start,
                   joined.v, joined.n, joined.faces, joined.extensions, joined.starts,
                   joined.layer_start, joined.ids, joined.coords, joined.coord_start,
                   joined.radii, joined.at, joined.cell, hidden_face, hidden_screen,
                   np.ascontiguousarray(np.concatenate(screen_coords), np.float64),
                   joined.core, out, unreflected, numba.get_num_threads())
    return out, (hidden_face >= 0) | unreflected


_LOOKUP_CHUNK = 256  # points claimed at a time by a thread in _virtual_parts


@njit(cache=True, parallel=True)
def _virtual_parts(points, point_start, chunk_start, v, n, faces, extensions, starts,
                   layer_start, ids, coords, coord_start, radii, at, cell, hidden_face,
                   hidden_screen, screen, cores, out, unreflected, threads):
    """_virtual for the points of several parts (part p's points rows point_start[p] ..;
    its vertices (and their screen positions `screen`), faces and extensions its rows of
    the joined arrays, starts as in _build_layers; its layers layer_start[p] ..; where
    each point is looked up, at and cell: _mark_parts'), the same arithmetic point by
    point. Each part's points go in chunks (chunk_start[p] ..) claimed by whichever
    thread is free (parallel.py): hidden points cost a few ns, the others two map reads
    far apart."""
    chunks = chunk_start[-1]
    claimed = counter()
    for _worker in prange(min(threads, chunks)):
        while True:
            c = claim(claimed)
            if c >= chunks:
                break
            p = 0
            while chunk_start[p + 1] <= c:
                p += 1
            a = point_start[p] + (c - chunk_start[p]) * _LOOKUP_CHUNK
            v0, v1 = starts[p, 0], starts[p + 1, 0]
            _virtual_chunk(points[a:min(point_start[p + 1], a + _LOOKUP_CHUNK)], v[v0:v1],
                           n[v0:v1], faces[starts[p, 1]:starts[p + 1, 1]],
                           extensions[starts[p, 3]:starts[p + 1, 3]], ids, coords,
                           coord_start, layer_start[p], radii[layer_start[p]:layer_start[p + 1]],
                           at[a:], cell[a:], hidden_face[a:], hidden_screen[a:],
                           screen[v0:v1], cores, out[a:], unreflected[a:])


@njit(cache=True, **_NO_COUNTS)
def _virtual_chunk(points, v, n, faces, extensions, ids, coords, coord_start, k0, radii, at,
                   cell, hidden_face, hidden_screen, screen, cores, out, unreflected):
    """_virtual's loop over one chunk of one part's points (its layers k0 .. of the joined
    ids, coords and cores; radii its own); reference counts off (_NO_COUNTS)."""
    for i in range(points.shape[0]):
        h = hidden_face[i]
        if h >= 0 and _through_hidden(points, i, faces, h, screen, v, n, hidden_screen, out):
            continue
        lo = cell[i, 2]
        k = k0 + lo
        _through_maps(points, i, v, n, faces, extensions, ids, k, coords, coord_start[k],
                      coord_start[k + 1], cores, at[i, 0], at[i, 1], cell[i, 0], cell[i, 1],
                      at[i, 2], radii[lo], radii[lo + 1], out, unreflected)
