"""Whitted ray tracing: the ground truth every other technique is measured against.

| parameter | type | default | meaning |
|---|---|---|---|
| `max_depth` | int in [0, 64] | 4 | mirror bounces followed; beyond, mirrors show (1 - r) * base |
| `samples` | int in [1, 16] | 1 | samples per pixel axis (s x s grid); Z, A, ids from the center |
| `embree` | "robust", "fast" | "robust" | Embree scenes as embreex builds them, or as Mitsuba 3 |

Triangles are intersected by Embree (objects and exact mirror triangles in two scenes, so a
mirror flush with a wall wins the depth tie); spheres and cylinders exactly in numba.
Primary rays run from the near plane to the far plane along each pixel center, like the
rasterizer's clipping, so both see the same surfaces. `embree = "robust"` builds the scenes
as embreex does (robust flag: no ray slips through the edge two triangles share);
`"fast"` as Mitsuba 3 builds its own (no flag, high build quality), for speed comparisons
like for like: about 0.8x the frame time, hits rounded otherwise (colours within 1e-3) and
a rare ray through an edge.
"""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, Field

from ...config.base import Strict, described


class RaytraceParams(Strict):
    model_config = ConfigDict(title="raytrace")

    name: Literal["raytrace"] = "raytrace"
    max_depth: int = Field(default=4, ge=0, le=64)
    samples: int = Field(default=1, ge=1, le=16)
    embree: Literal["robust", "fast"] = "robust"


Params = described(RaytraceParams, __doc__)
