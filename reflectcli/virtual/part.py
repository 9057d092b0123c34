"""Virtual vertices on one part of a mesh reflector: explosion maps built for this view
(hidden points looked up through the hidden map), then refined on the part's own pixels."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..camera import Camera
from ..fused import fma
from .explosion import ExplosionMaps, build_explosion_maps, ray_focus, virtual_vertices
from .refine import BOUNDARY, EXACT, NONE, refine_virtual
from .screen import screen_from_world
from .shape import PartShape
from .view import PartView


@njit(cache=True)
def _extent(vertices, normals, centre, scene_points, eye, front):
    """(bound, far): the farthest vertex's and the farthest scene point's distance from the
    map centre (_farthest); front (V,) the vertices facing the eye (n . (eye - v) >= 0).
    The numbers of numpy's whole-array version (np.linalg.norm(axis=1) of the differences,
    np.einsum's dot products; 60 us a part, 14 parts a mask frame) in its order of
    operations: a three-term dot product as (x0 y0 + x2 y2) + x1 y1 (explosion._focus_sums
    found it). With no scene point, far is 0 (numpy's max raised: a scene always has
    some)."""
    for k in range(vertices.shape[0]):
        t0, t1, t2 = eye[0] - vertices[k, 0], eye[1] - vertices[k, 1], eye[2] - vertices[k, 2]
        front[k] = (normals[k, 0] * t0 + normals[k, 2] * t2) + normals[k, 1] * t1 >= 0.0
    return _farthest(vertices, centre), _farthest(scene_points, centre)


@njit(cache=True, inline="always")
def _farthest(points, centre):
    """np.linalg.norm(points - centre, axis=1).max() (0 for no point): a norm's squares
    summed in order, a NaN distance the answer (as numpy's max)."""
    far = 0.0
    for k in range(points.shape[0]):
        d0, d1, d2 = points[k, 0] - centre[0], points[k, 1] - centre[1], \
            points[k, 2] - centre[2]
        d = math.sqrt((d0 * d0 + d1 * d1) + d2 * d2)
        if d > far or d != d:
            far = d
    return far


@njit(cache=True)
def _lookup_axis(normals, front, out):
    """out: a concave part's lookup axis, its front vertices' mean normal made unit (0 with
    no front vertex). The numbers of numpy's `normals[front].mean(axis=0)` divided by
    max(np.linalg.norm(mean), 1e-30) on this machine kind (tests/naive.py lookup_axis):
    the rows summed in order, divided by their count; the norm as OpenBLAS's fused chain
    sqrt(fma(m2, m2, fma(m1, m1, m0 m0))); Python's max keeping a NaN norm."""
    s0 = s1 = s2 = 0.0
    count = 0
    for k in range(normals.shape[0]):
        if front[k]:
            s0 += normals[k, 0]
            s1 += normals[k, 1]
            s2 += normals[k, 2]
            count += 1
    out[0] = out[1] = out[2] = 0.0
    if count:
        m0, m1, m2 = s0 / count, s1 / count, s2 / count
        length = math.sqrt(fma(m2, m2, fma(m1, m1, m0 * m0)))
        length = 1e-30 if length < 1e-30 else length
        out[0], out[1], out[2] = m0 / length, m1 / length, m2 / length


class ExplosionPart:
    """points -> (virtual points, flags) for one reflector part in one view. Flags mark
    points not exactly reflected: hidden ones (doubly virtual), and those found only past
    the part's edge. Its explosion maps are built when its points are known, and only
    where they look them up (build_explosion_maps' `lookups`): 0.7% of the texels on
    the mask. `maps` builds them whole (for tests and figures)."""

    def __init__(self, shape: PartShape, view: PartView, depth: np.ndarray,
                 grid: tuple[np.ndarray, np.ndarray] | None, camera: Camera,
                 clip_from_world: np.ndarray, scene_points: np.ndarray, center: str,
                 near_scale: float, resolution: int, layers: int,
                 focus: np.ndarray | None = None, extent: tuple | None = None,
                 together: tuple | None = None) -> None:
        """`focus`: ray_focus(shape.mesh, camera.eye) if already made (explosion.ray_foci
        makes a reflector's parts' at once). `extent`: (bound, far, front, screen, flip) as
        made here from the centre, if already made (partsetup.parts_extents). `together`:
        (JoinedParts of the reflector's parts, this part's index among them), with which
        parts_vertices sets up the maps of all parts at once."""
        part = shape.mesh
        # the map center (world): the reflection rays' focus, or the paper's vertex mean
        if center == "focus":
            centre = ray_focus(part, camera.eye) if focus is None else focus
        else:
            centre = part.vertices.mean(axis=0)
        if extent is None:
            front = np.empty(len(part.vertices), np.bool_)
            bound, far = _extent(part.vertices, part.normals, np.asarray(centre, np.float64),
                                 np.ascontiguousarray(scene_points, np.float64),
                                 np.asarray(camera.eye, np.float64), front)
            screen = screen_from_world(part.vertices, clip_from_world, camera.width,
                                       camera.height)[:, :2]
        else:
            bound, far, front, screen, flip = extent
        far *= 1.01
        near = max(bound * near_scale, 1e-6)
        # build_explosion_maps' arguments (before lookups), and the maps once built whole
        self.build_args = (part, camera.eye, centre, near, max(far, near * 1.01), resolution,
                           layers, shape.boundary)
        self.built: ExplosionMaps | None = None
        # a concave part looks maps up along its mean front normal (see virtual_vertices);
        # front-facing vertices as build_explosion_maps finds them (_extent)
        if extent is None:
            flip = np.zeros(3)
            if shape.concave:
                _lookup_axis(np.ascontiguousarray(part.normals, np.float64), front, flip)
        self.flip = flip
        self.view = view
        self.depth = depth
        self.grid = grid
        self.camera = camera
        self.clip_from_world = clip_from_world
        self.screen = screen  # (V, 2) the part's vertices on the screen
        self.together = together

    @property
    def maps(self) -> ExplosionMaps:
        """The part's explosion maps, whole."""
        if self.built is None:
            self.built = build_explosion_maps(*self.build_args)
        return self.built

    def __call__(self, points: np.ndarray, polygons: np.ndarray | None = None):
        """(virtual points, flags). With `polygons` (T, 3) point indices, points no ray of
        this part can reach are skipped (flagged, left in place) unless a polygon joins them
        to one it can: most points of a scene miss most parts of a mixed reflector."""
        n = len(points)
        todo = np.ones(n, bool)
        retry = reach = None
        tiles = self.view.tiles
        if tiles is not None:
            reach, retry, todo = tiles.scan_needed(points, self.grid[0], self.grid[1], polygons)
        virtual = points.astype(np.float64)  # a copy
        flags = np.ones(n, bool)
        if todo.any():
            # rows gathered by take and an index array: a boolean mask on (N, 3) rows took
            # 5-8x longer here, several times per part
            rows = np.flatnonzero(todo)
            camera = self.camera
            screen = self.view.points.of(points, self.clip_from_world, camera.width,
                                         camera.height)
            virtual[rows], flags[rows] = self.vertices(
                points.take(rows, axis=0), None if retry is None else retry.take(rows, axis=0),
                None if reach is None else reach.take(rows), screen.take(rows, axis=0))
        return virtual, flags

    def vertices(self, points: np.ndarray, retry: np.ndarray | None,
                 reach: np.ndarray | None = None, proj: np.ndarray | None = None):
        """Virtual vertices of `points` (world): explosion maps (hidden points through the
        hidden map), then the refinement on the part's pixels from `retry` seeds too.
        `proj`: screen_from_world of the points, if already made."""
        camera = self.camera
        if proj is None:
            proj = screen_from_world(points, self.clip_from_world, camera.width, camera.height)
        face = self.view.faces_behind(proj, self.depth)  # part face in front of a hidden point
        maps = self.built
        if maps is None:  # built for these points only (they are this part's lookups)
            maps = build_explosion_maps(*self.build_args, lookups=points,
                                        flip_axis=self.flip)
        virtual, flags = virtual_vertices(maps, points, face, proj[:, :2].copy(),
                                          self.screen, self.flip)
        if self.grid is not None:
            # seeds: where the map's virtual vertices land on the screen (on the eye ray
            # through the reflection point the map found); hidden points too: one behind the
            # reflector may still be reflected near its silhouette; where no reflection is
            # found it keeps its doubly virtual vertex
            seeds = screen_from_world(virtual, self.clip_from_world, camera.width,
                                      camera.height)[:, :2]
            refined, status = refine_virtual(points, seeds, self.view.owner, self.grid[0],
                                             self.grid[1], camera.eye, retry,
                                             reach=reach, part=self.view.part)
            virtual, flags = merge_refined(virtual, flags, refined, status)
        return virtual, flags


def merge_refined(virtual: np.ndarray, flags: np.ndarray, refined: np.ndarray,
                  status: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The map's answers (virtual (N, 3), flags (N,)) with the refinement's (refine_virtual:
    refined, status) where it found one: virtual written in place; flags kept where the
    refinement was not exact, and set where it ended at the part's boundary."""
    found = np.flatnonzero(status != NONE)
    virtual[found] = refined.take(found, axis=0)
    return virtual, (flags & (status != EXACT)) | (status == BOUNDARY)
