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
    balls: dict = field(default_factory=dict)  # (geometry key, reflector) -> ball

    def get(self, geometry: Geometry, n_objects: int, k: int, rule: TessellationRule,
            weld: bool = False, closed: tuple[int, ...] = ()) -> Tessellation:
        """Everything but reflector k (scene surface id n_objects + k), tessellated for it.
        `weld`: a new entry's equal points merged (`welded`: for vertex functions of one
        point at a time), asked for by `prepare`, where one-time work belongs; an entry
        already kept is returned as it is. `closed`: surface ids of other mirrors that are
        closed convex surfaces (spheres), whose faces turned away from the whole reflector
        are left out (`turned_away`)."""
        sid = n_objects + k
        # the reflector's radius about its corner mean scales the edge limits
        center, radius = self.ball(geometry, n_objects, k)
        max_edge = rule.max_edge
        if max_edge is None and rule.max_edge_radii is not None:
            max_edge = rule.max_edge_radii * radius
        # a fine mesh (a sphere of 48 segments) gains nothing from n x n more: its triangles
        # are split only as far as edges of min_edge_radii reflector radii
        min_edge = (rule.min_edge_radii or 0.0) * radius
        key = (geometry.key, k, rule.subdivisions, max_edge, min_edge, closed)
        if key not in self.entries:
            if len(self.entries) > CACHE_SIZE:
                self.entries.clear()
            drop = (turned_away(geometry.all_triangles(), closed, center, radius) if closed
                    else None)
            tess = reflected_objects(geometry, n_objects, sid, rule.subdivisions, max_edge,
                                     min_edge, drop)
            self.entries[key] = welded(tess) if weld else tess
        return self.entries[key]

    def ball(self, geometry: Geometry, n_objects: int, k: int) -> tuple[np.ndarray, float]:
        """Reflector k's ball (world): its corners' mean and the farthest corner's distance
        from it; kept per geometry state, since the lookup runs every frame."""
        ball = self.balls.get((geometry.key, k))
        if ball is None:
            pts = geometry.mirror_tris.corners[geometry.mirror_tris.surface == n_objects + k]
            pts = pts.reshape(-1, 3).astype(np.float64)
            center = pts.mean(axis=0)
            ball = (center, float(np.linalg.norm(pts - center, axis=1).max()))
            if len(self.balls) > CACHE_SIZE:
                self.balls.clear()
            self.balls[(geometry.key, k)] = ball
        return ball


def reflected_objects(geometry: Geometry, n_objects: int, sid: int, subdivisions: int,
                      max_edge: float | None, min_edge: float,
                      drop: np.ndarray | None = None) -> Tessellation:
    """Objects tessellated n x n and by edge length; other mirrors (seen with their base
    color only) are already fine meshes and keep their triangles, but those `drop` (T,)
    marks, if given."""
    tris = geometry.all_triangles()
    others = (tris.surface >= n_objects) & (tris.surface != sid)
    if drop is not None:
        others &= ~drop
    parts = []
    for keep, n, edge in ((tris.surface < n_objects, subdivisions, max_edge),
                          (others, 1, None)):
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


# the reflector's ball grown by this much of its radius: the vertex functions reflect on
# the exact shape, which may bulge past the corners that measured the ball
BALL_MARGIN = 0.05


def turned_away(tris: Triangles, closed: tuple[int, ...], center: np.ndarray,
                radius: float) -> np.ndarray:
    """(T,) bool: the triangles of the surfaces `closed` (each a closed convex mesh: its
    faces' outer side is the one away from its corners' mean) whose plane has the ball
    (center, radius, world; grown by BALL_MARGIN) wholly on its inner side.

    No point of the reflector sees such a face's outer side, and its inner side only
    through the rest of its closed surface, which lies in front: the face is never
    reflected. Other mirrors show their flat base color, so only the surface's outline
    could tell, and a face turned away from the whole reflector is not on it. On
    four-spheres a sphere sees about half of each other sphere's 3,968 faces so."""
    out = np.zeros(tris.count, bool)
    grown = radius * (1.0 + BALL_MARGIN)
    for surface in closed:
        mine = np.flatnonzero(tris.surface == surface)
        if not mine.size:
            continue
        c = tris.corners[mine].astype(np.float64)
        n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
        length = np.linalg.norm(n, axis=1)
        ok = length > 0.0
        n[ok] /= length[ok, None]
        inward = np.einsum("ij,ij->i", n, c.reshape(-1, 3).mean(axis=0) - c[:, 0]) > 0.0
        n[inward] *= -1.0
        out[mine] = ok & (np.einsum("ij,ij->i", n, center - c[:, 0]) + grown < 0.0)
    return out

