"""Distance cube maps (Szirmay-Kalos, Aszodi, Lazanyi, Premecz, "Approximate Ray-Tracing on
the GPU with Distance Impostors", Eurographics 2005), with layers (Umenhoffer, Patow,
Szirmay-Kalos, "Robust Multiple Specular Reflections and Refractions", GPU Gems 3 ch. 17).

| parameter | type | default | meaning |
|---|---|---|---|
| `resolution` | int in [4, 4096] | 256 | texels per cube face side |
| `layers` | int in [1, 8] | 4 | surfaces per texel, depth-peeled (1: the distance impostor) |
| `steps` | int in [1, 1024] | 32 | linear-march samples along the reflected ray |
| `refine_steps` | int in [0, 64] | 4 | secant steps after the march (0: the march alone) |
| `filter` | "nearest", "bilinear" | "bilinear" | colour filter at the hit direction |
| `capture_offset` | float >= 0.0 | 0.05 | planar mirrors: capture point in front of the center |
| `capture` | {mirror = xyz} | {} | capture point per mirror name (default: the center) |
| `update` | "once", "every", int >= 1 | "once" | capture at frame 0, every frame, or every N |
| `faces_per_frame` | int in [1, 6] | 6 | cube faces refreshed per update (1 to 6, round robin) |

Per reflector, a cube map is captured from a reference point (as envmap's, without the
reflector): per texel and layer the colour, eye depth and surface id of the first `layers`
surfaces along the texel's ray (reflectcli/maps/distance.py). Per mirror pixel the
reflected ray is searched against the stored surfaces (reflectcli/maps/distance_search.py):
`steps` samples spaced uniformly over the cube map, a crossing where the ray passes from in
front of a stored surface to behind the same surface, then `refine_steps` secant steps; the
colour is read where ray and stored surface meet. Rays that cross nothing are `holes` (an
EXR channel; they show the background); the log has the samples per ray (`search_steps`).

Where it is exact: surfaces seen from the reference point made of large planar faces (a box
or L-shaped room without free-standing objects seen from inside it): 1 / depth is linear in
face coordinates on a plane, so its bilinear interpolation is exact and one secant step
lands on the plane; there it equals box-projected envmap and the ray tracer up to colour
filtering. Where not: (1) surfaces hidden from the reference point (behind a free-standing
object): with `layers = 1` the ray finds the wall only where it is visible again, or
nothing (a hole); more layers store them; (2) silhouettes: a ray passing within a march
step of an object's edge may cross it between samples (thin objects are stepped over when
`steps` is smaller than the texels the ray's projection spans); (3) curved surfaces are
planes only per texel block; (4) texel resolution: depths and colours are sampled; (5)
maps hold no reflections (mirrors in them show their base colour); (6) moving objects are
as they were at the capture frame (`update`).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import ConfigDict, Field

from ...config.base import Strict, Vec3, described


class DistmapParams(Strict):
    model_config = ConfigDict(title="distmap")

    name: Literal["distmap"] = "distmap"
    resolution: int = Field(default=256, ge=4, le=4096, description="texels per face side")
    layers: int = Field(default=4, ge=1, le=8, description="surfaces per texel")
    steps: int = Field(default=32, ge=1, le=1024, description="linear-march samples")
    refine_steps: int = Field(default=4, ge=0, le=64, description="secant steps")
    filter: Literal["nearest", "bilinear"] = Field(default="bilinear", description="filter")
    capture_offset: float = Field(default=0.05, ge=0.0, description="planar capture offset")
    capture: dict[str, Vec3] = Field(default_factory=dict, description="capture points")
    update: Literal["once", "every"] | Annotated[int, Field(ge=1)] = Field(
        default="once", description="capture at frame 0, every frame or every N frames")
    faces_per_frame: int = Field(default=6, ge=1, le=6, description="faces per update")


Params = described(DistmapParams, __doc__)
