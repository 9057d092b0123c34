"""What ssr and ppr keep from frame to frame: the primary pass's scratch (its triangle ids
and barycentrics too: read only while the frame renders) and the screen-space stages'
(ray table, march outputs, pyramid, scatter buffers, the colour copy rays sample)."""

from __future__ import annotations

import numpy as np

from ...raster.rasterize import RasterWorkspace
from ...raster.rasterize.buffers import scratch
from ...scene.types import Scene
from .fallback import Fallback


def screen_state(scene: Scene, fallback: Fallback) -> dict:
    """A screen-space technique's prepared state (a workspace set to None: fresh arrays
    every frame)."""
    return {"scene": scene, "fallback": fallback, "primary": RasterWorkspace(ids=True),
            "screen": RasterWorkspace()}


def color_copy(workspace: RasterWorkspace | None, rgb: np.ndarray) -> np.ndarray:
    """The primary colours as rays sample them (mirrors: (1 - r) * base), in the
    workspace's kept array: written whole, so nothing of an earlier frame is read."""
    colors = scratch(workspace, "colors", rgb.shape, np.float32)
    np.copyto(colors, rgb)
    return colors
