"""Screen-space reflections: rays marched over the frame's own colour and depth buffers.

| parameter | type | default | meaning |
|---|---|---|---|
| `march` | "linear", "dda", "hiz" | "hiz" | eye-space steps; pixel DDA; min-depth pyramid |
| `thickness` | float > 0.0 | 0.1 | eye-space depth a surface extends behind its front |
| `stride` | float in [1.0, 64.0] | 1.0 | dda: pixels per step (bisection refines a hit) |
| `jitter` | float in [0.0, 1.0] | 0.0 | dda: start offset, a fixed per-pixel stride fraction |
| `max_steps` | int in [1, 65536] | 1024 | steps (linear, dda) or cell lookups (hiz) per ray |
| `max_distance` | float > 0.0 | 20.0 | ray length, eye-space units (clipped at near) |
| `resolve` | "pixel", "surface" | "pixel" | hit colour: hit pixel's, or its triangle shaded |
| `fallback` | "none", "envmap", "rerender" | "none" | a miss: base, box-projected probe, rerender |

`resolve = "surface"` intersects the ray with the plane of the triangle the primary pass
left at the hit pixel and shades that point (beyond the papers). `fallback`: "none" leaves
(1 - r) * base, "envmap" a box-projected cube map per mirror (`envmap` with parallax =
"box"), "rerender" the re-rendered reflection (planar mirrors; curved ones keep the base).

Every mirror pixel (planar or curved) starts a ray at its point with the mirror's normal
there (r = 2 n (n.v) - v); the ray is marched over the primary pass's eye-space depth
buffer and a hit shows the colour at the hit pixel, times the reflectance. Channels:
`ssr_hit` (1 hit, 0 miss), `ssr_distance` (eye-space distance along the ray to the hit),
`confidence` (the engines' fade: screen border, grazing and camera-facing rays, depth gap;
written, not applied) and `source` (0 not a mirror, 1 screen space, 2 rerender, 3 envmap,
4 base only), `holes` (1 where a mirror pixel shows only its base: the bench's holes
column). The log gets `cells_per_ray` (depth lookups per marched ray) and
`hit_fraction`.

What it cannot see: anything off screen (tops of tall objects above the frame, everything
behind the camera: camera-facing rays leave through the near plane), anything occluded in
the primary frame (behind another object, the backs of objects: a ray that passes behind an
object hits its front face if within `thickness`, else finds nothing), and the depth
buffer's missing thickness: too small a `thickness` lets rays slip behind thin objects
between pixels, too large a one makes rays hit "behind" objects that are not there.
Mirrors seen in the reflection show (1 - r) * base (one level, like rerender with
max_depth = 1); a reflector never sees itself.
"""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, Field

from ...config.base import Strict, described


class SsrParams(Strict):
    model_config = ConfigDict(title="ssr")

    name: Literal["ssr"] = "ssr"
    march: Literal["linear", "dda", "hiz"] = "hiz"
    thickness: float = Field(default=0.1, gt=0.0)
    stride: float = Field(default=1.0, ge=1.0, le=64.0)
    jitter: float = Field(default=0.0, ge=0.0, le=1.0)
    max_steps: int = Field(default=1024, ge=1, le=65536)
    max_distance: float = Field(default=20.0, gt=0.0)
    resolve: Literal["pixel", "surface"] = "pixel"
    fallback: Literal["none", "envmap", "rerender"] = "none"


Params = described(SsrParams, __doc__)
