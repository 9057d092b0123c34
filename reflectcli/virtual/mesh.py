"""A reflector as an indexed mesh: its triangle soup welded into shared vertices."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
