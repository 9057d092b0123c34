"""Curved mirrors by virtual objects (Ofek & Rappoport): each reflected scene vertex gets a
virtual vertex, and the virtual objects are rasterized like any others, masked by the
reflector's pixels and blended.

| parameter | type | default | meaning |
|---|---|---|---|
| `method` | "auto", "explosion", "sphere", "extrusion" | "auto" | how virtual vertices are found |
| `explosion.resolution` | int in [16, 4096] | 200 | explosion map side in texels |
| `explosion.near_scale` | float > 1.0 | 1.1 | near sphere radius / reflector bounding radius |
| `explosion.layers` | int in [2, 64] | 6 | maps on spheres from near to far (2: the paper's pair) |
| `explosion.center` | "mean", "focus" | "focus" | map center: vertex mean, or rays' focus |
| `explosion.refine` | "screen", "none" | "screen" | refine map answers on the reflector's pixels |
| `tessellation.subdivisions` | int in [1, 64] | 7 | reflected triangles split n x n (paper: 7) |
| `tessellation.max_edge` | float > 0 | (unset) | and further until no edge is longer (world) |
| `tessellation.max_edge_radii` | float > 0 | 1.0 | the same in reflector radii, if no max_edge |
| `tessellation.min_edge_radii` | float >= 0 | 0.05 | no split below this edge (reflector radii) |
| `reflector_test` | "none", "clip_planes", "zbuffer" | "zbuffer" | front-of-reflector test |
| `decompose` | "auto", "none" | "auto" | split mesh reflectors into convex and concave parts |
| `decompose_overrides` | {mirror = "auto" or "none"} | {} | per-mirror choice |

`auto` uses the exact sphere method for spheres, the extrusion method (a binary search in
the cross-section) for cylinders and extrusion mirrors (the TV of Fig. 17), exact
mirroring for planar mirrors (the special case), and explosion maps for other meshes.
Explosion maps (centered where the reflection rays come closest together, their focus, or
at the paper's vertex mean; near: a sphere `near_scale` times the reflector's bounding
radius from there; far: one bounding the scene) and the hidden map (an item buffer and
z-buffer of the reflector alone) are rebuilt per frame and part
(reflectcli/virtual/explosion.py); `explosion.refine = "screen"` then refines each map
answer on the reflector's own pixels, Gauss-Newton on the reflection law
(reflectcli/virtual/refine.py). Mixed reflectors are split into convex, concave and
crease parts (reflectcli/virtual/convexity.py), one image per part.
Reflected objects are everything but the reflector, tessellated by `tessellation`; mirrors
among them show their base color (one level of recursion, as in the paper's figures).
`reflector_test`: `zbuffer` rejects virtual fragments at or in front of the reflector's own
depth (the paper's second z-buffer), `clip_planes` clips against the faces of the
reflector's bounding box that face the viewer, `none` leaves doubly virtual polygons be.
"""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, Field

from ...config.base import Strict, described


class ExplosionParams(Strict):
    resolution: int = Field(default=200, ge=16, le=4096)
    near_scale: float = Field(default=1.1, gt=1.0)
    layers: int = Field(default=6, ge=2, le=64)
    center: Literal["mean", "focus"] = "focus"
    refine: Literal["screen", "none"] = "screen"


class TessellationParams(Strict):
    subdivisions: int = Field(default=7, ge=1, le=64)
    max_edge: float | None = Field(default=None, gt=0)
    max_edge_radii: float | None = Field(default=1.0, gt=0)
    min_edge_radii: float | None = Field(default=0.05, ge=0)


class VirtualParams(Strict):
    model_config = ConfigDict(title="virtual")

    name: Literal["virtual"] = "virtual"
    method: Literal["auto", "explosion", "sphere", "extrusion"] = "auto"
    explosion: ExplosionParams = Field(default_factory=ExplosionParams)
    tessellation: TessellationParams = Field(default_factory=TessellationParams)
    reflector_test: Literal["none", "clip_planes", "zbuffer"] = "zbuffer"
    decompose: Literal["auto", "none"] = "auto"
    decompose_overrides: dict[str, Literal["auto", "none"]] = Field(default_factory=dict)


Params = described(VirtualParams, __doc__)
