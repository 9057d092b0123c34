"""Pixel-projected reflections (Cichocki 2017; Far Cry 5) for planar mirrors.

| parameter | type | default | meaning |
|---|---|---|---|
| `fill` | bool | true | close one-pixel holes (an empty pixel between two reached ones) |
| `resolve` | "pixel", "surface" | "pixel" | colour: source pixel's, or its triangle shaded |
| `fallback` | "none", "envmap", "rerender" | "none" | what a pixel no source reached shows |

`resolve` and `fallback` work as in `ssr` ("surface": the mirror pixel's reflected ray
meets the plane of the source pixel's triangle, shaded there).

A projection pass mirrors every object pixel of the primary frame across each planar mirror
plane and scatters it to the screen pixel where it appears reflected, keeping per target the
point nearest the mirror (a packed 64-bit key min: distance bits, then the source index, so
the result is the same on any thread count); a reflection pass resolves each mirror pixel
from that buffer, filling the one-pixel holes the scatter leaves. Channels `ppr_hit`,
`ppr_distance` (mirror point to the source point) and `source` (as `ssr`: 0 not a mirror,
1 projected, 2 rerender, 3 envmap, 4 base only) and `holes` (source 4).

What it cannot see: anything off screen or occluded in the primary frame (the backs of
objects, what stands behind another object), and where the reflection magnifies the frame
(a floor seen at a grazing angle stretches each source pixel over several mirror pixels)
the holes grow past one pixel and stay misses. Curved mirrors show (1 - r) * base (or the
fallback); mirrors are not sources (one level of reflection).
"""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict

from ...config.base import Strict, described


class PprParams(Strict):
    model_config = ConfigDict(title="ppr")

    name: Literal["ppr"] = "ppr"
    fill: bool = True
    resolve: Literal["pixel", "surface"] = "pixel"
    fallback: Literal["none", "envmap", "rerender"] = "none"


Params = described(PprParams, __doc__)
