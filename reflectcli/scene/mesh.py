"""A triangle soup with per-corner attributes: the one shape every primitive becomes.

Per-corner (not per-vertex) UVs and normals let seams and hard edges live in the same
arrays without splitting vertices; the renderers index them by triangle and barycentrics.
All arrays are in the primitive's local (object) space until `transformed`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True)
class Mesh:
    """Triangles with corner positions, UVs and shading normals (float64, object space)."""

    corners: np.ndarray  # (F, 3, 3) corner positions
    uvs: np.ndarray  # (F, 3, 2) corner texture coordinates
    normals: np.ndarray  # (F, 3, 3) corner shading normals, unit length
    # (F,) int32 closed piece of each triangle, -1 for none: a piece's triangles close a
    # surface with every face turned outward, so from an eye outside it a ray meets a front
    # face first and its back faces may be culled (raster/closed.py). None: no piece.
    # Only the primitives that close (`closed`) make pieces; other operations drop them.
    pieces: np.ndarray | None = None

    def __post_init__(self) -> None:
        f = self.corners.shape[0]
        assert self.corners.shape == (f, 3, 3), self.corners.shape
        assert self.uvs.shape == (f, 3, 2), self.uvs.shape
        assert self.normals.shape == (f, 3, 3), self.normals.shape
        assert self.pieces is None or self.pieces.shape == (f,), self.pieces.shape

    def closed(self) -> Mesh:
        """This mesh as one closed piece (its maker vouches that it closes outward)."""
        return replace(self, pieces=np.zeros(self.triangle_count, np.int32))

    @property
    def piece_count(self) -> int:
        """1 + the highest piece id (0 without pieces)."""
        if self.pieces is None or self.pieces.size == 0:
            return 0
        return int(self.pieces.max()) + 1

    @property
    def triangle_count(self) -> int:
        return int(self.corners.shape[0])

    def face_normals(self) -> np.ndarray:
        """Geometric normals (F, 3) from the winding: (c1 - c0) x (c2 - c0), normalised."""
        n = np.cross(
            self.corners[:, 1] - self.corners[:, 0], self.corners[:, 2] - self.corners[:, 0]
        )
        length = np.linalg.norm(n, axis=1, keepdims=True)
        return n / np.where(length > 0, length, 1.0)

    def areas(self) -> np.ndarray:
        n = np.cross(
            self.corners[:, 1] - self.corners[:, 0], self.corners[:, 2] - self.corners[:, 0]
        )
        return 0.5 * np.linalg.norm(n, axis=1)

    def transformed(self, matrix: np.ndarray) -> Mesh:
        """Apply a 4x4 affine object-to-world matrix; normals use the inverse transpose."""
        m = np.asarray(matrix, dtype=np.float64)
        corners = self.corners @ m[:3, :3].T + m[:3, 3]
        normal_matrix = np.linalg.inv(m[:3, :3]).T
        normals = self.normals @ normal_matrix.T
        length = np.linalg.norm(normals, axis=2, keepdims=True)
        normals = normals / np.where(length > 0, length, 1.0)
        if np.linalg.det(m[:3, :3]) < 0:  # a mirroring transform flips the winding
            corners = corners[:, ::-1]
            normals = normals[:, ::-1]
            uvs = self.uvs[:, ::-1]
        else:
            uvs = self.uvs
        # a mirroring transform's flipped winding keeps a closed piece's faces outward
        return Mesh(corners, uvs.copy(), normals, self.pieces)

    def without_degenerate(self, min_area: float = 1e-12) -> Mesh:
        """Without triangles of area <= min_area. A piece that loses a triangle with any
        area at all (a solid too small for its triangles) has holes: it is open after.
        (A pole's zero-area triangles go and close nothing.)"""
        areas = self.areas()
        keep = areas > min_area
        pieces = self.pieces
        if pieces is not None:
            holed = np.unique(pieces[(areas > 0) & ~keep])
            pieces = np.where(np.isin(pieces, holed[holed >= 0]), -1, pieces)[keep]
            pieces = pieces.astype(np.int32)
        return Mesh(self.corners[keep], self.uvs[keep], self.normals[keep], pieces)

    @staticmethod
    def concatenate(meshes: list[Mesh]) -> Mesh:
        if not meshes:
            empty3 = np.zeros((0, 3, 3))
            return Mesh(empty3, np.zeros((0, 3, 2)), empty3.copy())
        pieces = None
        if any(m.pieces is not None for m in meshes):
            pieces = joined_pieces([(m.pieces, m.piece_count, m.triangle_count)
                                    for m in meshes])
        return Mesh(
            np.concatenate([m.corners for m in meshes]),
            np.concatenate([m.uvs for m in meshes]),
            np.concatenate([m.normals for m in meshes]),
            pieces,
        )

    @staticmethod
    def flat(corners: np.ndarray, uvs: np.ndarray) -> Mesh:
        """A mesh whose shading normals are its face normals (hard edges everywhere)."""
        corners = np.asarray(corners, dtype=np.float64)
        n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        length = np.linalg.norm(n, axis=1, keepdims=True)
        n = n / np.where(length > 0, length, 1.0)
        return Mesh(corners, np.asarray(uvs, dtype=np.float64), np.repeat(n[:, None, :], 3, axis=1))


def joined_pieces(parts: list[tuple[np.ndarray | None, int, int]]) -> np.ndarray:
    """(T,) int32 piece ids of parts (ids (T_i,) or None for no piece, piece count, triangle
    count) concatenated in order, each part's ids renumbered after the ones before (-1
    stays -1)."""
    ids, first = [], 0
    for part, count, triangles in parts:
        if part is None:
            ids.append(np.full(triangles, -1, np.int32))
        else:
            ids.append(np.where(part >= 0, part + first, -1).astype(np.int32))
        first += count
    return np.concatenate(ids) if ids else np.zeros(0, np.int32)
