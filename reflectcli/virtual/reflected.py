"""The reflected objects of a reflector: every scene triangle but the reflector's own,
tessellated finely enough that virtual objects, which bend only at their vertices, follow
a curved mirror. Kept per geometry state, since a static scene tessellates the same way
every frame."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ..camera import Camera
from ..raster.closed import near_reach, seen_from_outside
from ..raster.rasterize import RasterWorkspace
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
    """Tessellations by (geometry key, reflector, edge lengths, pieces holding the eye,
    exact)."""

    entries: dict = field(default_factory=dict)
    balls: dict = field(default_factory=dict)  # (geometry key, reflector) -> ball

    def get(self, geometry: Geometry, n_objects: int, k: int, rule: TessellationRule, *,
            exact: bool, weld: bool = False, inside: tuple[int, ...] = ()) -> Tessellation:
        """Everything but reflector k (scene surface id n_objects + k), tessellated for it,
        without the faces of closed pieces turned away from the whole reflector
        (`turned_away`), except the faces of the pieces in `inside` (those whose box holds
        the eye: `pieces_holding_eye`). `exact`: the reflector's vertex function is exact
        (sphere, extrusion, planar); False (explosion parts) leaves out the other mirrors'
        pieces' faces only: their virtual objects are approximate, with cracks along
        creases that the objects' far sides happen to cover (on the mask at 512 px,
        leaving those out made 30 mirror pixels worse). `weld`: a new entry's equal points
        merged (`welded`: for vertex functions of one point at a time), asked for by
        `prepare` and by frames for explosion reflectors; an entry already kept is
        returned as it is (welded or not, the same corners)."""
        sid = n_objects + k
        # the reflector's radius about its corner mean scales the edge limits
        center, radius = self.ball(geometry, n_objects, k)
        max_edge = rule.max_edge
        if max_edge is None and rule.max_edge_radii is not None:
            max_edge = rule.max_edge_radii * radius
        # a fine mesh (a sphere of 48 segments) gains nothing from n x n more: its triangles
        # are split only as far as edges of min_edge_radii reflector radii
        min_edge = (rule.min_edge_radii or 0.0) * radius
        key = (geometry.key, k, rule.subdivisions, max_edge, min_edge, inside, exact)
        if key not in self.entries:
            if len(self.entries) > CACHE_SIZE:
                self.entries.clear()
            tris = geometry.all_triangles()
            drop = turned_away(tris, geometry.closed_piece, inside, center, radius)
            if not exact:
                drop &= tris.surface >= n_objects
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
    color only) are already fine meshes and keep their triangles; the triangles `drop`
    (T,) marks, if given, left out of both."""
    tris = geometry.all_triangles()
    objects = tris.surface < n_objects
    others = (tris.surface >= n_objects) & (tris.surface != sid)
    if drop is not None:
        objects &= ~drop
        others &= ~drop
    parts = []
    for keep, n, edge in ((objects, subdivisions, max_edge), (others, 1, None)):
        parts.append(tessellate(Triangles(*(a[keep] for a in (
            tris.corners, tris.uvs, tris.normals, tris.material, tris.surface))),
            n, edge, min_edge))
    return concatenate_tessellations(parts)


def welded(tess: Tessellation) -> Tessellation:
    """`tess` with its bit-for-bit equal points made one, in order of first appearance. A
    grid point on an edge two original triangles share is made by both (four-spheres:
    43,858 points a reflector, 13,480 distinct), so a vertex function of one point at a time
    ran up to six times for the same point; the mask's 14,184 points a part are 2,972 (its
    frame 2x faster). Equal bits in, equal bits out: the corners gathered from the virtual
    points are the same. Explosion parts also read the polygons, to compute a point that
    no ray of the part reaches where a polygon joins it to one that does (tiles.joined);
    welded, a point shared by two original triangles is joined through the polygons of
    both. Where one triangle's copy was joined and the other's not, the other's polygons
    around it reach no point of the part, and were skipped (every corner flagged); they
    stay skipped as long as a point joined but not reached ends flagged, as every one
    does on the mask (a refinement that finds nothing keeps the map's answer, flagged
    where the map hides it). No pixel changed on any bundled scene drawn through explosion
    maps (mask, concave-mirror lit and unlit; four-spheres, cylinder and tv-extrusion with
    method "explosion"; 256 and 512 px; a review's sweep of 14 scenes, 3 sizes and 8
    parameter variants)."""
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


def pieces_holding_eye(geometry: Geometry, camera: Camera,
                       workspace: RasterWorkspace | None = None) -> tuple[int, ...]:
    """Ids of the closed pieces whose box, widened by the near plane's reach, holds the
    eye: `turned_away` may not drop their faces. Usually none (the key prepare's
    tessellations are made with). Kept in `workspace`, if given, while the boxes and the
    eye stay (50-160 us of numpy between a frame's kernels)."""
    def make() -> tuple[int, ...]:
        outside = seen_from_outside(geometry, camera)
        return () if outside is None else tuple(np.flatnonzero(~outside).tolist())

    if workspace is None:
        return make()
    key = (np.asarray(camera.eye, np.float64).tobytes(), near_reach(camera))
    return workspace.kept("pieces_holding_eye", geometry.closed_boxes, key, make)


def turned_away(tris: Triangles, piece: np.ndarray | None, inside: tuple[int, ...],
                center: np.ndarray, radius: float) -> np.ndarray:
    """(T,) bool: the triangles of closed pieces (`piece` (T,), -1: open; Mesh.pieces:
    each piece closes outward, its faces wound counter-clockwise seen from outside) but
    those `inside`, whose plane has the reflector's ball (center, radius, world; grown by
    BALL_MARGIN) wholly on its inner side.

    No reflector point the eye sees lies inside a piece whose box does not hold the eye
    (the eye ray to it would enter the piece first), and a ray from a point outside a
    closed piece meets one of its inner sides only after entering it through a face turned
    toward the ray: a face whose plane hides the whole ball from its outer side is never
    the first hit of a reflected ray. On four-spheres a sphere sees about half of each
    other sphere's 3,968 faces so, and the tabletop's underside and the legs' far sides
    not at all."""
    out = np.zeros(tris.count, bool)
    if piece is None:
        return out
    mine = np.flatnonzero((piece >= 0) & ~np.isin(piece, np.asarray(inside, np.int64)))
    if not mine.size:
        return out
    c = tris.corners[mine].astype(np.float64)
    n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])  # outward (counter-clockwise)
    length = np.linalg.norm(n, axis=1)
    ok = length > 0.0
    n[ok] /= length[ok, None]
    grown = radius * (1.0 + BALL_MARGIN)
    out[mine] = ok & (np.einsum("ij,ij->i", n, center - c[:, 0]) + grown < 0.0)
    return out
