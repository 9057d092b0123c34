"""A reflector seen alone from the eye: its own item buffer and z-buffer (the paper's
hidden map, without what hides it in the scene, so that points behind it still find it),
per pixel its reflection rays (refine.reflector_grid), and per part the pixels it covers
and their tiles (tiles.PartTiles). All of it depends on the reflector's shape and the view
only, so it is kept while neither changes (a still camera, a rigid reflector)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit, prange

from ..camera import Camera
from ..raster.rasterize import rasterize
from .refine import reflector_grid
from .shape import ReflectorShape
from .tiles import PartTiles

CACHE_SIZE = 8  # views kept before the cache starts over (each holds a few screen buffers)


@dataclass(frozen=True)
class PartView:
    hidden_map: np.ndarray  # (H, W) int32 screen: the part's face under each pixel, or -1
    inside: np.ndarray | None  # (H, W) bool screen: hidden_map >= 0 (with refinement only)
    tiles: PartTiles | None  # (with refinement only)


@dataclass(frozen=True)
class ReflectorView:
    depth: np.ndarray  # (H, W) screen: eye depth of the reflector alone
    grid: tuple[np.ndarray, np.ndarray] | None  # (Q, R) (H, W, 3) world, if refining
    parts: tuple[PartView, ...]  # as shape.parts


def reflector_view(corners: np.ndarray, normals: np.ndarray, shape: ReflectorShape,
                   camera: Camera, clip_from_world: np.ndarray, refine: bool) -> ReflectorView:
    """From the reflector's triangle soup (T, 3, 3) corners and normals (world space)."""
    count = len(corners)
    alone = rasterize(corners, np.zeros(count, np.uint8), clip_from_world, camera.width,
                      camera.height)
    grid = None
    if refine:
        grid = reflector_grid(alone.triangle, alone.b1, alone.b2, corners, normals, camera.eye)
    h, w = alone.triangle.shape
    local = np.full((len(shape.parts), count + 1), -1, np.int32)  # face -> part face
    for p, part in enumerate(shape.parts):
        local[p, part.faces] = np.arange(len(part.faces))
    hidden = np.empty((len(shape.parts), h, w), np.int32)  # half the bytes to write
    inside = np.empty((len(shape.parts), h, w), np.bool_)
    marks = np.zeros((len(shape.parts), h // TILE + 1, w // TILE + 1), np.bool_)
    part_views(alone.triangle, local, TILE, hidden, inside, marks)
    parts = []
    for p in range(len(shape.parts)):
        tiles = None
        if grid is not None:
            tiles = PartTiles(inside[p], grid[0], grid[1], TILE,
                              tiles=np.flatnonzero(marks[p]))
        parts.append(PartView(hidden[p], inside[p] if grid is not None else None, tiles))
    return ReflectorView(alone.depth, grid, tuple(parts))


TILE = 12  # pixels a side of the refinement's tiles (tiles.PartTiles)


@njit(cache=True, parallel=True)
def part_views(triangle, local, size, hidden, inside, marks):
    """Per part p, in one pass over the reflector's item buffer: hidden[p] (H, W) its face
    under each pixel (local[p, reflector face], -1 where none; the buffer's -1 reads the
    last entry, -1), inside[p] = hidden[p] >= 0, and marks[p, ty, tx] set for the tiles
    of size x size pixels holding one of its pixels (so tile ids ty * (W // size + 1) + tx
    come out ascending, as np.unique of the pixels' ids gives them)."""
    h, w = triangle.shape
    for row in prange(local.shape[0] * h):  # part by part: each writes its planes in order
        p = row // h
        y = row - p * h
        for x in range(w):
            f = local[p, triangle[y, x]]
            hidden[p, y, x] = f
            inside[p, y, x] = f >= 0
            if f >= 0:
                # rows of one tile row may be on two threads: both store the same True
                # (a benign race; no value depends on which store lands)
                marks[p, y // size, x // size] = True


@dataclass
class ViewCache:
    """ReflectorViews by (shape key, view)."""

    entries: dict = field(default_factory=dict)

    def get(self, shape_key: tuple, corners: np.ndarray, normals: np.ndarray,
            shape: ReflectorShape, camera: Camera, clip_from_world: np.ndarray,
            refine: bool) -> ReflectorView:
        key = (shape_key, clip_from_world.tobytes(), np.asarray(camera.eye).tobytes(),
               camera.width, camera.height, refine)
        if key not in self.entries:
            if len(self.entries) > CACHE_SIZE:
                self.entries.clear()
            self.entries[key] = reflector_view(corners, normals, shape, camera,
                                               clip_from_world, refine)
        return self.entries[key]
