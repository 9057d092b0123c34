"""Convex, concave and crease parts of a mesh reflector: the explosion maps assume a
surface of one convexity, so a mixed reflector gets one image per part."""

from __future__ import annotations

import numpy as np

from .mesh import IndexedMesh


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
