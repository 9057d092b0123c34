"""Curved mirrors by virtual objects (Ofek & Rappoport): each reflected scene vertex gets a
virtual vertex, and the virtual objects are rasterized like any others, masked by the
reflector's pixels and blended.

| parameter | type | default | meaning |
|---|---|---|---|
| `method` | "auto", "explosion", "sphere", "extrusion" | "auto" | how virtual vertices are found |
| `explosion.resolution` | int | 200 | explosion map side in texels |
| `explosion.near_scale` | float | 1.1 | near sphere radius / reflector bounding radius |
| `explosion.layers` | int | 6 | maps on spheres from near to far (2: the paper's pair) |
| `explosion.center` | "mean", "focus" | "focus" | map center: vertex mean, or rays' focus |
| `explosion.refine` | "screen", "none" | "screen" | refine map answers on the reflector's pixels |
| `tessellation.subdivisions` | int | 7 | each reflected triangle split n x n (paper: 7x7) |
| `tessellation.max_edge` | float | (unset) | and further until no edge is longer (world) |
| `tessellation.max_edge_radii` | float | 1.0 | the same in reflector radii, if no max_edge |
| `tessellation.min_edge_radii` | float | 0.05 | no split into edges shorter (reflector radii) |
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

from ...config.base import Strict


class ExplosionParams(Strict):
    resolution: int = Field(default=200, ge=16, le=4096, description="map side, texels")
    near_scale: float = Field(default=1.1, gt=1.0, description="near sphere / bounding radius")
    layers: int = Field(default=6, ge=2, le=64, description="maps from near to far sphere")
    center: Literal["mean", "focus"] = Field(
        default="focus", description="map center: vertex mean or the reflection rays' focus")
    refine: Literal["screen", "none"] = Field(
        default="screen", description="refine map answers on the reflector's pixels")


class TessellationParams(Strict):
    subdivisions: int = Field(default=7, ge=1, le=64, description="n x n per triangle")
    max_edge: float | None = Field(default=None, gt=0, description="longest edge (world)")
    max_edge_radii: float | None = Field(
        default=1.0, gt=0, description="longest edge in reflector radii (if no max_edge)")
    min_edge_radii: float | None = Field(
        default=0.05, ge=0, description="no split into edges shorter, in reflector radii")


class Params(Strict):
    model_config = ConfigDict(title="virtual")

    name: Literal["virtual"] = "virtual"
    method: Literal["auto", "explosion", "sphere", "extrusion"] = Field(
        default="auto", description="virtual vertex method")
    explosion: ExplosionParams = Field(default_factory=ExplosionParams,
                                       description="explosion maps")
    tessellation: TessellationParams = Field(default_factory=TessellationParams,
                                             description="reflected objects")
    reflector_test: Literal["none", "clip_planes", "zbuffer"] = Field(
        default="zbuffer", description="virtual geometry in front of the reflector")
    decompose: Literal["auto", "none"] = Field(default="auto", description="convex parts")
    decompose_overrides: dict[str, Literal["auto", "none"]] = Field(
        default_factory=dict, description="per mirror")

