"""A reflector seen alone from the eye: its own item buffer and z-buffer (the paper's
hidden map, without what hides it in the scene, so that points behind it still find it),
per pixel its reflection rays (refine.reflector_rays), and per part the pixels it covers
and their tiles (tiles.PartTiles). All of it depends on the reflector's shape and the view
only, so it is kept while neither changes (a still camera, a rigid reflector)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit, prange

from ..camera import Camera
from ..raster.rasterize import RasterWorkspace, rasterize
from ..raster.rasterize.buffers import scratch
from .refine import reflector_rays
from .screen import screen_from_world
from .shape import ReflectorShape
from .tiles import PartTiles

CACHE_SIZE = 8  # views kept before the cache starts over (each holds a few screen buffers)


@dataclass
class PointsOnScreen:
    """The scene points' screen positions in one view, shared by the reflector's parts:
    each part looks up the same points (a part's subset indexes them; projecting each
    subset anew gave the same numbers, 14 times a frame on the mask)."""

    points: np.ndarray | None = None  # the array last projected (kept: compared by identity)
    screen: np.ndarray | None = None  # (N, 3) screen_from_world of it

    def of(self, points: np.ndarray, clip_from_world: np.ndarray, width: int,
           height: int) -> np.ndarray:
        """screen_from_world(points, ...) (the view's camera), made once per read-only
        points array (a tessellation's: never written after it is made); a writable one is
        projected on every call."""
        if self.points is not points:
            self.screen = screen_from_world(points, clip_from_world, width, height)
            self.points = None if points.flags.writeable else points
        return self.screen


@dataclass(frozen=True)
class PartView:
    """Part `part` of the reflector's item buffer. The reflector's pixels are split among
    its parts in one plane (`owner`, shared by the parts), not one plane per part: a
    part's pixels are found where owner == part, its faces through `local`."""

    # (H, W) int16 (int32 past 32,767 parts) screen: the part under each pixel, or -1 (shared)
    owner: np.ndarray
    part: int  # this part's index, as `owner` holds it
    triangle: np.ndarray  # (H, W) int32 screen: the reflector face under each pixel, or -1
    local: np.ndarray  # (F + 1,) int32: reflector face -> this part's face, or -1 (last: -1)
    tiles: PartTiles | None  # (with refinement only)
    points: PointsOnScreen  # the scene points on the screen (one for the whole reflector)
    # (P, F + 1) every part's `local` (its row `part`: this one's), shared by the parts
    tables: np.ndarray | None = None

    def faces_behind(self, screen: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """(N,) int64: for points at `screen` (N, 3: screen x, y, eye depth) behind the
        reflector alone (deeper than `depth` (H, W) at their pixel, in front of the eye),
        the part's face in front of them (the hidden map), else -1."""
        out = np.empty(screen.shape[0], np.int64)
        _faces_behind(np.ascontiguousarray(screen, np.float64), depth, self.triangle,
                      self.local, out)
        return out


@njit(cache=True)
def _faces_behind(screen, depth, triangle, local, out):
    """PartView.faces_behind. A point counts if its depth is > 0 and its x, y lie in
    [0, W) x [0, H) (the same as flooring them first; NaN fails every test). One thread:
    a few ns a point."""
    for i in range(screen.shape[0]):
        out[i] = face_behind(screen[i, 0], screen[i, 1], screen[i, 2], depth, triangle, local)


@njit(cache=True, inline="always")
def face_behind(x, y, z, depth, triangle, local):
    """_faces_behind's answer for one point at screen (x, y), eye depth z."""
    h, w = depth.shape
    if not (z > 0.0 and x >= 0.0 and y >= 0.0 and x < w and y < h):
        return -1
    xi, yi = int(math.floor(x)), int(math.floor(y))
    if z > depth[yi, xi]:
        return local[triangle[yi, xi]]
    return -1


@dataclass(frozen=True)
class ReflectorView:
    depth: np.ndarray  # (H, W) screen: eye depth of the reflector alone
    # (Q, R) (H, W, 3) world, if refining: defined on the pixels a part owns (the rows'
    # spans), unwritten elsewhere (every reader tests the owner plane first)
    grid: tuple[np.ndarray, np.ndarray] | None
    parts: tuple[PartView, ...]  # as shape.parts
    # where depth, the item buffer, the owner plane and the grid are held (None: arrays of
    # their own): a dropped view's serves the next view (ViewCache)
    workspace: RasterWorkspace | None = None


def reflector_view(corners: np.ndarray, normals: np.ndarray, shape: ReflectorShape,
                   camera: Camera, clip_from_world: np.ndarray, refine: bool,
                   workspace: RasterWorkspace | None = None) -> ReflectorView:
    """From the reflector's triangle soup (T, 3, 3) corners and normals (world space).
    `workspace` (outputs=True): where the view's screen arrays are made, and the
    rasterizer's scratch (the view then holds it; valid while the view is in use). The
    item buffer and depth (no stencil: every pixel) and the owner plane are written whole;
    the grid where a part owns a pixel, the only pixels read (`ReflectorView.grid`)."""
    assert workspace is None or workspace.outputs
    count = len(corners)
    alone = rasterize(corners, np.zeros(count, np.uint8), clip_from_world, camera.width,
                      camera.height, workspace=workspace)
    h, w = alone.triangle.shape
    parts = len(shape.parts)
    # face -> part face, face -> part (the parts split the faces)
    assert count == len(shape.mesh.faces)
    local, part_of = shape.face_parts
    owner = scratch(workspace, "view_owner", (h, w), part_of.dtype)
    marks = np.zeros((parts, h // TILE + 1, w // TILE + 1), np.bool_)
    spans = np.empty((h, 2), np.int64)
    part_views(alone.triangle, part_of, TILE, owner, marks, spans)
    grid = None
    if refine:  # Q and R where a part owns a pixel (the rows' spans of them)
        grid = reflector_rays(alone, corners, normals, camera.eye, spans,
                              (scratch(workspace, "view_q", (h, w, 3), np.float64),
                               scratch(workspace, "view_r", (h, w, 3), np.float64)))
    views = []
    on_screen = PointsOnScreen()
    tiles = [None] * parts
    if grid is not None:  # every part's tiles in one region
        tiles = PartTiles.of_parts(owner, grid[0], grid[1], TILE,
                                   [np.flatnonzero(marks[p]) for p in range(parts)])
    for p in range(parts):
        views.append(PartView(owner, p, alone.triangle, local[p], tiles[p], on_screen,
                              local))
    return ReflectorView(alone.depth, grid, tuple(views), workspace)


TILE = 12  # pixels a side of the refinement's tiles (tiles.PartTiles)


@njit(cache=True, parallel=True)
def part_views(triangle, part_of, size, owner, marks, spans):
    """In one pass over the reflector's item buffer: owner (H, W) the part under each pixel
    (part_of[reflector face], -1 where none; the buffer's -1 reads the last entry, -1),
    marks[p, ty, tx] set for the tiles of size x size pixels holding a pixel of part p (so
    tile ids ty * (W // size + 1) + tx come out ascending, as np.unique of the pixels' ids
    gives them), and spans (H, 2) per row the columns from its first part pixel to past
    its last (0, 0 if none)."""
    h, w = triangle.shape
    for y in prange(h):
        lo, hi = w, 0
        for x in range(w):
            p = part_of[triangle[y, x]]
            owner[y, x] = p
            if p >= 0:
                # rows of one tile row may be on two threads: both store the same True
                # (a benign race; no value depends on which store lands)
                marks[p, y // size, x // size] = True
                lo = min(lo, x)
                hi = x + 1
        spans[y, 0] = lo if hi > 0 else 0
        spans[y, 1] = hi


@dataclass
class ViewCache:
    """ReflectorViews by (shape key, view). Each view's screen arrays (item buffer,
    depth, owner plane, ray grid: 14 MB at 512 x 512) live in a workspace of its own; the
    workspaces of dropped views (the cache started over, or `forget`) serve the new views
    that follow, so that a moving camera (or the bench's repeats) does not make them anew
    each frame. A view's arrays are read only while its frame renders."""

    entries: dict = field(default_factory=dict)
    spare: list[RasterWorkspace] = field(default_factory=list)  # dropped views' workspaces

    def get(self, shape_key: tuple, corners: np.ndarray, normals: np.ndarray,
            shape: ReflectorShape, camera: Camera, clip_from_world: np.ndarray,
            refine: bool) -> ReflectorView:
        key = (shape_key, clip_from_world.tobytes(), np.asarray(camera.eye).tobytes(),
               camera.width, camera.height, refine)
        if key not in self.entries:
            if len(self.entries) > CACHE_SIZE:
                self.forget()
            workspace = self.spare.pop() if self.spare else RasterWorkspace(outputs=True)
            self.entries[key] = reflector_view(corners, normals, shape, camera,
                                               clip_from_world, refine, workspace)
        return self.entries[key]

    def forget(self) -> None:
        """Drop every view (a new view of each reflector is made when next asked for);
        their workspaces are kept for the views to come."""
        self.spare.extend(view.workspace for view in self.entries.values()
                          if view.workspace is not None)
        self.entries.clear()
