"""A reflector seen alone from the eye: its own item buffer and z-buffer (the paper's
hidden map, without what hides it in the scene, so that points behind it still find it),
per pixel its reflection rays (refine.reflector_grid), and per part the pixels it covers
and their tiles (tiles.PartTiles). All of it depends on the reflector's shape and the view
only, so it is kept while neither changes (a still camera, a rigid reflector)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..camera import Camera
from ..raster.rasterize import rasterize
from .refine import reflector_grid
from .shape import ReflectorShape
from .tiles import PartTiles

CACHE_SIZE = 8  # views kept before the cache starts over (each holds a few screen buffers)


@dataclass(frozen=True)
class PartView:
    hidden_map: np.ndarray  # (H, W) int64 screen: the part's face under each pixel, or -1
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
    parts = []
    for part in shape.parts:
        local = np.full(count + 1, -1, np.int64)  # reflector face -> part face (-1: none)
        local[part.faces] = np.arange(len(part.faces))
        hidden_map = local[alone.triangle]
        inside = (hidden_map >= 0) if grid is not None else None
        tiles = PartTiles(inside, grid[0], grid[1]) if grid is not None else None
        parts.append(PartView(hidden_map, inside, tiles))
    return ReflectorView(alone.depth, grid, tuple(parts))


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
