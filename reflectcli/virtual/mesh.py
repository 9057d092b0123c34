"""Mesh helpers for the virtual-object technique: welding a reflector's triangle soup into an
indexed mesh, splitting it into convex and concave parts, and tessellating reflected objects."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene.types import Triangles


@dataclass(frozen=True)
class IndexedMesh:
    """A reflector as shared vertices (world space) with unit normals, and triangles."""

    vertices: np.ndarray  # (V, 3) float64
    normals: np.ndarray  # (V, 3) float64, unit
    faces: np.ndarray  # (F, 3) int64
    soup_index: np.ndarray  # (F,) index of each face in the triangle soup it came from


def weld(corners: np.ndarray, normals: np.ndarray, soup_index: np.ndarray | None = None,
         decimals: int = 6) -> IndexedMesh:
    """Merge coincident corners (rounded to `decimals`); a vertex's normal is the mean of its
    corners' normals, so a smooth soup stays smooth and a seam closes."""
    pts = corners.reshape(-1, 3).astype(np.float64)
    key = np.round(pts, decimals)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    n = np.zeros((first.size, 3))
    np.add.at(n, inverse, normals.reshape(-1, 3).astype(np.float64))
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    faces = inverse.reshape(-1, 3)
    if soup_index is None:
        soup_index = np.arange(faces.shape[0])
    return IndexedMesh(pts[first], n, faces.astype(np.int64), np.asarray(soup_index))


def vertex_convexity(mesh: IndexedMesh) -> np.ndarray:
    """+1 where the surface bends away from its normal around a vertex (convex seen from the
    front), -1 where it bends toward it (concave): the sign of the mean offset of the
    neighbours along the vertex normal (negative offset = neighbours below = convex)."""
    v, n, f = mesh.vertices, mesh.normals, mesh.faces
    total = np.zeros(len(v))
    count = np.zeros(len(v))
    for a, b in ((0, 1), (1, 2), (2, 0), (1, 0), (2, 1), (0, 2)):
        i, j = f[:, a], f[:, b]
        np.add.at(total, i, np.einsum("ij,ij->i", v[j] - v[i], n[i]))
        np.add.at(count, i, 1)
    offset = total / np.maximum(count, 1)
    return np.where(offset <= 0, 1, -1)


def convexity_parts(mesh: IndexedMesh, flat_degrees: float = 0.5, smallest: float = 0.005,
                    crease_factor: float = 4.0) -> list[np.ndarray]:
    """Face index sets of connected regions of one convexity, grown across edges.

    Each interior edge bends convexly (the vertex normals at its ends diverge: the normal
    curvature along it is positive), concavely, or not at all (the normals turn by under
    `flat_degrees`); being measured with the vertex normals, this does not depend on how a
    surface was triangulated. A face takes the sign of its edges' summed normal turns. Faces
    of one sign join across edges that bend their way or not at all, so pieces meeting in a
    crease (a valley between two convex pieces, a ridge around a concave one) come apart.
    Faces bending over `crease_factor` times more sharply than the mesh's median face (mean
    normal turn per edge) are crease strips: they form parts of their own, whatever their
    sign but one, so that a strip's wide fan of reflections does not overlap a smooth piece's.
    Regions under `smallest` of the faces (the strip along a crease) join the neighbour they
    share most edges with: they are too thin to show a reflection of their own. A
    single-signed mesh is one part."""
    v, f, vn = mesh.vertices, mesh.faces, mesh.normals
    nf = len(f)
    # interior edges as (face, neighbour, vertex, vertex)
    pairs = np.stack([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], 1).reshape(-1, 2)
    keys = np.sort(pairs, 1)
    owner = np.repeat(np.arange(nf), 3)
    order = np.lexsort((keys[:, 1], keys[:, 0]))
    k, o = keys[order], owner[order]
    same = np.all(k[1:] == k[:-1], axis=1)
    fa, fb = o[:-1][same], o[1:][same]
    va, vb = k[:-1][same, 0], k[:-1][same, 1]
    edge = v[vb] - v[va]
    turn = np.einsum("ij,ij->i", vn[vb] - vn[va], edge) / np.maximum(
        np.linalg.norm(edge, axis=1), 1e-30)  # ~ normal curvature x edge length (radians)
    edge_sign = np.where(np.abs(turn) < np.radians(flat_degrees), 0, np.sign(turn))
    signed = turn
    face_sum = np.zeros(nf)
    np.add.at(face_sum, fa, signed)
    np.add.at(face_sum, fb, signed)
    face_sign = np.where(face_sum < 0, -1, 1)
    # how sharply each face bends: its edges' mean normal turn
    sharp = np.zeros(nf)
    edges_of = np.zeros(nf)
    np.add.at(sharp, fa, np.abs(turn))
    np.add.at(sharp, fb, np.abs(turn))
    np.add.at(edges_of, fa, 1)
    np.add.at(edges_of, fb, 1)
    sharp = sharp / np.maximum(edges_of, 1) + np.radians(flat_degrees)
    crease = sharp > crease_factor * np.median(sharp)
    smooth = ~crease[fa] & ~crease[fb]
    join = (smooth & (face_sign[fa] == face_sign[fb])
            & ((edge_sign == 0) | (edge_sign == face_sign[fa]))) | (
        crease[fa] & crease[fb] & (face_sign[fa] == face_sign[fb]))
    parent = np.arange(nf)

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for a, b in zip(fa[join], fb[join], strict=True):
        ra, rb = find(a), find(b)
        if ra != rb:
            parent[ra] = rb
    # fold regions that are too small into the neighbour sharing most edges with them
    minimum = max(1, int(smallest * nf))
    islands = set()  # small regions with no neighbour: they stay parts of their own
    while True:
        roots = np.array([find(i) for i in range(nf)])
        sizes = np.bincount(roots, minlength=nf)
        small = [r for r in np.unique(roots) if sizes[r] < minimum and r not in islands]
        if not small or len(np.unique(roots)) == 1:
            break
        r = min(small, key=lambda x: (sizes[x], x))
        ra, rb = roots[fa], roots[fb]
        touching = np.concatenate([rb[ra == r], ra[rb == r]])
        touching = touching[touching != r]
        if touching.size == 0:
            islands.add(r)
            continue
        counts = np.bincount(touching, minlength=nf)
        parent[r] = int(np.argmax(counts))
    roots = np.array([find(i) for i in range(nf)])
    parts = [np.flatnonzero(roots == r) for r in np.unique(roots)]
    return sorted(parts, key=lambda p: int(p[0]))


@dataclass(frozen=True)
class Tessellation:
    """Subdivided triangles whose corners index shared grid points, so that a per-point
    computation (virtual vertices) runs once per point, not once per corner."""

    triangles: Triangles  # corners == points[corner_index]
    points: np.ndarray  # (P, 3) float64
    corner_index: np.ndarray  # (T, 3) int64


def _grid(n: int):
    """Barycentric grid of a triangle split n x n: (weights (G, 3), faces (S, 3))."""
    index = {}
    weights = []
    for a in range(n + 1):
        for b in range(n + 1 - a):
            index[(a, b)] = len(weights)
            weights.append((1 - (a + b) / n, a / n, b / n))
    faces = []
    for a in range(n):
        for b in range(n - a):
            faces.append((index[(a, b)], index[(a + 1, b)], index[(a, b + 1)]))
            if a + b + 1 < n:
                faces.append((index[(a + 1, b)], index[(a + 1, b + 1)], index[(a, b + 1)]))
    return np.array(weights), np.array(faces, np.int64)


def subdivide(tris: Triangles, n: int) -> Tessellation:
    """Split every triangle into n^2 by a regular barycentric grid; attributes interpolated
    (the reflected objects' tessellation: virtual objects bend only at their vertices)."""
    w, faces = _grid(max(n, 1))
    corner_w = w[faces]  # (S, 3, 3): per sub-corner, weights of the original corners
    t, g, s = tris.count, len(w), len(faces)

    def interp(attr):
        return np.einsum("skc,tcd->tskd", corner_w, attr.astype(np.float64))

    points = np.einsum("gc,tcd->tgd", w, tris.corners.astype(np.float64)).reshape(-1, 3)
    corner_index = (np.arange(t)[:, None, None] * g + faces[None]).reshape(-1, 3)
    out = Triangles(
        points[corner_index].astype(np.float32),
        interp(tris.uvs).reshape(t * s, 3, 2).astype(np.float32),
        interp(tris.normals).reshape(t * s, 3, 3).astype(np.float32),
        np.repeat(tris.material, s),
        np.repeat(tris.surface, s),
    )
    return Tessellation(out, points, corner_index)


def tessellate(tris: Triangles, subdivisions: int, max_edge: float | None,
               min_edge: float = 0.0) -> Tessellation:
    """Each triangle split n x n, n = max(subdivisions, ceil(longest edge / max_edge)): the
    paper's per-object grid, refined where triangles are large against the reflector; but
    never into edges under `min_edge` (n <= longest / min_edge), so fine meshes stay fine
    without multiplying their points."""
    if tris.count == 0 or (max_edge is None and min_edge <= 0.0):
        return subdivide(tris, subdivisions)
    c = tris.corners.astype(np.float64)
    longest = np.max(np.linalg.norm(c - np.roll(c, 1, axis=1), axis=2), axis=1)
    n = np.full(tris.count, float(subdivisions))
    if max_edge is not None:
        n = np.maximum(n, np.ceil(longest / max_edge))
    if min_edge > 0.0:
        n = np.minimum(n, np.maximum(1.0, np.floor(longest / min_edge)))
    n = np.minimum(n, 256).astype(np.int64)
    n = _within_budget(n)
    parts = []
    for value in np.unique(n):
        pick = n == value
        parts.append(subdivide(Triangles(*(a[pick] for a in (
            tris.corners, tris.uvs, tris.normals, tris.material, tris.surface))), int(value)))
    return concatenate_tessellations(parts)


def _within_budget(n: np.ndarray) -> np.ndarray:
    """Scale the splits down (never below the scene's own triangles) so the tessellation
    stays within MAX_TESSELLATED_TRIANGLES: a huge object next to a small reflector would
    otherwise ask for hundreds of millions of triangles and never finish a frame."""
    from ..config.limits import MAX_TESSELLATED_TRIANGLES

    total = float(np.sum(n.astype(np.float64) ** 2))
    if total <= MAX_TESSELLATED_TRIANGLES:
        return n
    scale = np.sqrt(MAX_TESSELLATED_TRIANGLES / total)
    capped = np.maximum(1, np.floor(n * scale)).astype(np.int64)
    import logging

    logging.getLogger("reflect").warning(
        "virtual: tessellation of the reflected objects capped at %d triangles (asked for "
        "%d); raise tessellation.max_edge for fewer", int(np.sum(capped**2)), int(total))
    return capped


def concatenate_tessellations(parts: list[Tessellation]) -> Tessellation:
    offsets = np.cumsum([0] + [len(p.points) for p in parts[:-1]])
    return Tessellation(
        Triangles(*(np.concatenate([getattr(p.triangles, f) for p in parts]) for f in
                    ("corners", "uvs", "normals", "material", "surface"))),
        np.concatenate([p.points for p in parts]),
        np.concatenate([p.corner_index + o for p, o in zip(parts, offsets, strict=True)]),
    )
