"""What a mesh reflector's shape alone decides, computed once per shape: its welded mesh,
its convex / concave / crease parts, and per part the sub-mesh, whether it is concave and
its boundary edges. A reflector that does not deform keeps all of it from frame to frame."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .convexity import convexity_parts, vertex_convexity
from .explosion import boundary_edges
from .mesh import IndexedMesh, weld

CACHE_SIZE = 16  # shapes kept before the cache starts over


@dataclass(frozen=True)
class PartShape:
    """One part of a reflector (all of it, if not decomposed)."""

    faces: np.ndarray  # (F,) indices of the part's faces among the reflector's triangles
    mesh: IndexedMesh  # the part alone, world space
    concave: bool  # its vertices bend toward their normals on average
    boundary: np.ndarray  # (B, 3) int64 (face, i, j): edges of one face only, in mesh indices


@dataclass(frozen=True)
class JoinedParts:
    """A reflector's parts' meshes in one set of arrays: part p's vertices and normals are
    rows vstart[p] .. vstart[p + 1], its faces rows fstart[p] .. (indices into its own
    vertices), its boundary edges rows bstart[p] .. ((face, i, j) in its own indices)."""

    vertices: np.ndarray  # (V, 3) float64, world
    normals: np.ndarray  # (V, 3) float64
    vstart: np.ndarray  # (P + 1,) int64
    faces: np.ndarray  # (F, 3) int64
    fstart: np.ndarray  # (P + 1,) int64
    boundary: np.ndarray  # (B, 3) int64
    bstart: np.ndarray  # (P + 1,) int64


def starts_of(sizes) -> np.ndarray:
    """(N + 1,) int64 where each of N runs of `sizes` starts in their joined array, and
    its end."""
    return np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)


def join_parts(meshes: list, boundaries: list[np.ndarray]) -> JoinedParts:
    """JoinedParts of the parts' IndexedMeshes and boundary edges (B, 3), in order."""
    starts = starts_of
    return JoinedParts(
        np.ascontiguousarray(np.concatenate([m.vertices for m in meshes]), np.float64),
        np.ascontiguousarray(np.concatenate([m.normals for m in meshes]), np.float64),
        starts([len(m.vertices) for m in meshes]),
        np.ascontiguousarray(np.concatenate([m.faces for m in meshes]), np.int64),
        starts([len(m.faces) for m in meshes]),
        np.ascontiguousarray(np.concatenate([np.asarray(b, np.int64).reshape(-1, 3)
                                             for b in boundaries]), np.int64),
        starts([len(np.asarray(b).reshape(-1, 3)) for b in boundaries]))


@dataclass(frozen=True)
class ReflectorShape:
    mesh: IndexedMesh  # the whole reflector, welded
    parts: tuple[PartShape, ...]

    @cached_property
    def face_parts(self) -> tuple[np.ndarray, np.ndarray]:
        """(local, part_of): local (P, F + 1) int32 each reflector face's index among its
        part's faces, -1 in other parts' rows (and in the last column, which an item
        buffer's -1 reads); part_of (F + 1,) each face's part (int16 below 32,768 parts:
        half the owner plane's reads), -1 last. Made once per shape (view.reflector_view
        made them for every view); shared, not to be written."""
        count = len(self.mesh.faces)
        local = np.full((len(self.parts), count + 1), -1, np.int32)
        part_of = np.full(count + 1, -1, np.int16 if len(self.parts) < 2**15 else np.int32)
        for p, part in enumerate(self.parts):
            local[p, part.faces] = np.arange(len(part.faces))
            part_of[part.faces] = p
        return local, part_of

    @cached_property
    def joined(self) -> JoinedParts:
        """The parts' meshes and boundary edges joined (partsetup.py's kernels take every
        part's at once); made once per shape, shared, not to be written."""
        return join_parts([part.mesh for part in self.parts],
                          [part.boundary for part in self.parts])


def reflector_shape(corners: np.ndarray, normals: np.ndarray, decompose: bool) -> ReflectorShape:
    """From a reflector's triangle soup (T, 3, 3) corners and normals (world space)."""
    mesh = weld(corners, normals)
    faces_of_parts = convexity_parts(mesh) if decompose else [np.arange(len(mesh.faces))]
    parts = []
    for faces in faces_of_parts:
        part = sub_mesh(mesh, faces)
        parts.append(PartShape(faces, part, bool(vertex_convexity(part).mean() < 0),
                               boundary_edges(part.faces)))
    return ReflectorShape(mesh, tuple(parts))


def sub_mesh(mesh: IndexedMesh, faces: np.ndarray) -> IndexedMesh:
    """The faces `faces` of `mesh` with only the vertices they use, renumbered."""
    used, inverse = np.unique(mesh.faces[faces].reshape(-1), return_inverse=True)
    return IndexedMesh(mesh.vertices[used], mesh.normals[used], inverse.reshape(-1, 3),
                       mesh.soup_index[faces])


@dataclass
class ShapeCache:
    """ReflectorShapes by the content of their triangle soup and the decomposition asked."""

    entries: dict = field(default_factory=dict)
    # soup keys of one frame's soup arrays by slice: a static scene hands the same arrays
    # every frame (Geometry.all_triangles), and hashing a mesh's soup took milliseconds a
    # frame. Only the latest arrays are held (an animated scene's earlier frames are let go).
    keys: dict = field(default_factory=dict)
    arrays: tuple = ()

    def soup_key(self, all_corners: np.ndarray, all_normals: np.ndarray, first: int,
                 count: int) -> tuple:
        """soup_key of all_corners / all_normals [first:first + count], kept while the same
        arrays come back (scene geometry is not written after it is built)."""
        if (len(self.arrays) != 2 or self.arrays[0] is not all_corners
                or self.arrays[1] is not all_normals):
            self.arrays = (all_corners, all_normals)
            self.keys.clear()
        key = self.keys.get((first, count))
        if key is None:
            key = soup_key(all_corners[first:first + count], all_normals[first:first + count])
            self.keys[(first, count)] = key
        return key

    def get(self, soup: tuple, corners: np.ndarray, normals: np.ndarray,
            decompose: bool) -> ReflectorShape:
        """`soup`: soup_key(corners, normals)."""
        key = (soup, decompose)
        if key not in self.entries:
            if len(self.entries) > CACHE_SIZE:
                self.entries.clear()
            self.entries[key] = reflector_shape(corners, normals, decompose)
        return self.entries[key]


def soup_key(corners: np.ndarray, normals: np.ndarray) -> tuple:
    """Equal keys: equal triangle soups (so equal shapes)."""
    digest = hashlib.blake2b(corners.tobytes() + normals.tobytes(), digest_size=16)
    return digest.hexdigest(), corners.shape, corners.dtype.str, normals.dtype.str
