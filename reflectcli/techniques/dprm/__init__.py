"""Depth-preserving reflection maps (Bastos & Stuerzlinger): precomputed zexel maps per
planar mirror, forward-warped into the mirror's pixels every frame.

| parameter | type | default | meaning |
|---|---|---|---|
| `maps.count` | int in [1, 4096] | 16 | maps per mirror, on a hemisphere behind it (1: its axis) |
| `maps.resolution` | int in [8, 8192] | 512 | zexels per map side |
| `maps.layout` | "grid", "fibonacci" | "grid" | viewpoint layout (grid needs a square count) |
| `maps.radius` | float > 0 | mirror diagonal | viewpoint distance from the mirror's center |
| `maps.spread` | degrees in (0, 90) | 45.0 | half-angle of the cap of viewpoints around the axis |
| `maps.per_frame` | int in [1, 64] | 4 | maps warped per frame: those nearest the reflected eye |
| `maps.lod` | bool | false | warp the mip level whose density matches the mirror on screen |
| `fill.splat` | 1, 3, 5, "adaptive" | 1 | splat footprint in pixels (adaptive: from the warp) |
| `fill.temporal` | bool | false | keep the previous frame's reflection where no zexel lands |
| `update` | "once", "every", int >= 1 | "once" | capture at frame 0, every frame, or every N |
| `occlusion` | "zbuffer", "ordered" | "zbuffer" | nearest zexel wins, or McMillan's order |
| `reconstruct` | "color", "surface" | "surface" | zexel colors, or shade each pixel's own point |

Per frame and visible planar mirror: the eye is reflected across the mirror (equations 1
and 2: M = E - 2 (N.E + d) N; the reflected view direction R_d = E_d - 2 (N.E_d) N, which is
the paper's 2 (N.E_d) N - E_d with E_d pointing toward the eye), the `per_frame` maps whose
viewpoints are nearest M are warped (reflectcli/maps/warp/), holes are filled as asked, and
the mirror pixels get (1 - r) * base + r * reflected. The warp's cost depends on the zexels,
not on the scene's polygons. Maps are captured at frame 0: objects that move later are not
in them (a warning says so), unless `update` recaptures them every N frames or every frame
(reflectcli/maps/update.py; the cache key holds the capture frame). Pixels no zexel
reached are `holes` (an EXR channel) and show the background. Curved mirrors show (1 - r) * base.
Splats of 3 and 5 pixels (z-buffer occlusion) keep each pixel's own zexel where it lies on
the front surface of the pixel's square, and give the others (empty pixels, pixels a nearer
surface covers nearby) the front surface's zexel landing nearest their center.

`reconstruct = "surface"` (beyond the paper): maps also keep the triangle each zexel saw,
and a reached pixel intersects its own reflected ray (from M through the pixel center) with
that triangle's plane and shades the point there, as the rasterizer would. Point resampling
of colors puts one-pixel seams along every texture edge (its error floor); this removes
them wherever the zexel's triangle is the surface under the pixel center, or a coplanar
neighbour with the same texture mapping. It costs a shading pass over the mirror's pixels
and stays independent of the polygon count.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import ConfigDict, Field, model_validator

from ...config.base import Strict, UpdatePolicy, described


class DprmMaps(Strict):
    count: int = Field(default=16, ge=1, le=4096)
    resolution: int = Field(default=512, ge=8, le=8192)
    layout: Literal["grid", "fibonacci"] = "grid"
    radius: float | None = Field(default=None, gt=0)
    spread: float = Field(default=45.0, gt=0, lt=90)
    per_frame: int = Field(default=4, ge=1, le=64)
    lod: bool = False

    @model_validator(mode="after")
    def _count_fits_layout(self) -> DprmMaps:
        if self.layout == "grid" and self.count != math.isqrt(self.count) ** 2:
            raise ValueError(f"count = {self.count} does not fit layout 'grid' (needs a "
                             "square: 1, 4, 9, 16, ...)")
        if self.per_frame > self.count:
            raise ValueError(f"per_frame = {self.per_frame} exceeds count = {self.count}")
        return self


class DprmFill(Strict):
    splat: Literal[1, 3, 5, "adaptive"] = 1
    temporal: bool = False


class DprmParams(Strict):
    model_config = ConfigDict(title="dprm")

    name: Literal["dprm"] = "dprm"
    maps: DprmMaps = Field(default_factory=DprmMaps)
    fill: DprmFill = Field(default_factory=DprmFill)
    update: UpdatePolicy = "once"
    occlusion: Literal["zbuffer", "ordered"] = "zbuffer"
    reconstruct: Literal["color", "surface"] = "surface"


Params = described(DprmParams, __doc__)
