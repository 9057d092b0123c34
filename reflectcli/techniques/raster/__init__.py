"""Plain rasterization, no reflections: the shared first pass of every raster technique.

| parameter | type | default | meaning |
|---|---|---|---|
| (none) | | | mirrors show (1 - r) * base, like `raytrace` with `max_depth = 0` |

Useful as a baseline for cost and to check the rasterizer against the ray tracer.
"""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict

from ...config.base import Strict, described


class RasterParams(Strict):
    model_config = ConfigDict(title="raster")

    name: Literal["raster"] = "raster"


Params = described(RasterParams, __doc__)
