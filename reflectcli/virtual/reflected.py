"""The reflected objects of a reflector: every scene triangle but the reflector's own,
tessellated finely enough that virtual objects, which bend only at their vertices, follow
a curved mirror. Kept per geometry state, since a static scene tessellates the same way
every frame."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ..scene.types import Geometry, Triangles
from .tessellation import Tessellation, concatenate_tessellations, tessellate

CACHE_SIZE = 16  # tessellations kept before the cache starts over


class TessellationRule(Protocol):
    """How finely reflected objects are split (the technique's `tessellation` Params)."""

    subdivisions: int
    max_edge: float | None  # world units
    max_edge_radii: float | None  # reflector radii, if no max_edge
    min_edge_radii: float | None  # reflector radii


@dataclass
class ReflectedCache:
    """Tessellations by (geometry key, reflector, edge lengths)."""

    entries: dict = field(default_factory=dict)
    radii: dict = field(default_factory=dict)  # (geometry key, reflector) -> radius

    def get(self, geometry: Geometry, n_objects: int, k: int, rule: TessellationRule,
            weld: bool = False) -> Tessellation:
        """Everything but reflector k (scene surface id n_objects + k), tessellated for it.
        `weld`: a new entry's equal points merged (`welded`: for vertex functions of one
        point at a time), asked for by `prepare`, where one-time work belongs; an entry
        already kept is returned as it is."""
        sid = n_objects + k
        # the reflector's radius about its corner mean (world units) scales the edge limits
        # (kept per geometry state: the lookup runs every frame)
        radius = self.radii.get((geometry.key, k))
        if radius is None:
            pts = geometry.mirror_tris.corners[geometry.mirror_tris.surface == sid]
            pts = pts.reshape(-1, 3).astype(np.float64)
            radius = float(np.linalg.norm(pts - pts.mean(axis=0), axis=1).max())
            if len(self.radii) > CACHE_SIZE:
                self.radii.clear()
            self.radii[(geometry.key, k)] = radius
        max_edge = rule.max_edge
        if max_edge is None and rule.max_edge_radii is not None:
            max_edge = rule.max_edge_radii * radius
        # a fine mesh (a sphere of 48 segments) gains nothing from n x n more: its triangles
        # are split only as far as edges of min_edge_radii reflector radii
        min_edge = (rule.min_edge_radii or 0.0) * radius
        key = (geometry.key, k, rule.subdivisions, max_edge, min_edge)
        if key not in self.entries:
            if len(self.entries) > CACHE_SIZE:
                self.entries.clear()
            tess = reflected_objects(geometry, n_objects, sid, rule.subdivisions, max_edge,
                                     min_edge)
            self.entries[key] = welded(tess) if weld else tess
        return self.entries[key]


def reflected_objects(geometry: Geometry, n_objects: int, sid: int, subdivisions: int,
                      max_edge: float | None, min_edge: float) -> Tessellation:
    """Objects tessellated n x n and by edge length; other mirrors (seen with their base
    color only) are already fine meshes and keep their triangles."""
    tris = geometry.all_triangles()
    parts = []
    for keep, n, edge in ((tris.surface < n_objects, subdivisions, max_edge),
                          ((tris.surface >= n_objects) & (tris.surface != sid), 1, None)):
        parts.append(tessellate(Triangles(*(a[keep] for a in (
            tris.corners, tris.uvs, tris.normals, tris.material, tris.surface))),
            n, edge, min_edge))
    return concatenate_tessellations(parts)


def welded(tess: Tessellation) -> Tessellation:
    """`tess` with its bit-for-bit equal points made one, in order of first appearance. A
    grid point on an edge two original triangles share is made by both (four-spheres:
    43,858 points a reflector, 13,480 distinct), so a vertex function of one point at a time
    ran up to six times for the same point. Equal bits in, equal bits out: the corners
    gathered from the virtual points are the same."""
    points = np.ascontiguousarray(tess.points)
    keys = points.view(np.dtype((np.void, points.itemsize * points.shape[1]))).ravel()
    _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    order = np.argsort(first)  # distinct points in order of first appearance
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    corner_index = rank[inverse.ravel()][tess.corner_index]
    return Tessellation(tess.triangles, points[first[order]], corner_index)
