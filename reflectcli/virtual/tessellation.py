"""Tessellating reflected objects: virtual objects bend only at their vertices, so reflected
triangles are split on a barycentric grid whose points are shared between corners."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene.types import Triangles


@dataclass(frozen=True)
class Tessellation:
    """Subdivided triangles whose corners index shared grid points, so that a per-point
    computation (virtual vertices) runs once per point, not once per corner."""

    triangles: Triangles  # corners == points[corner_index]
    points: np.ndarray  # (P, 3) float64, read-only
    corner_index: np.ndarray  # (T, 3) int64

    def __post_init__(self) -> None:
        # read-only: a view's projection of these points is kept by the array's identity
        # (view.PointsOnScreen), which a write in place would leave stale
        self.points.flags.writeable = False


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
