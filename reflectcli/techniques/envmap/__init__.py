"""Environment mapping: a cube or sphere map per reflector, indexed by the reflection vector.

| parameter | type | default | meaning |
|---|---|---|---|
| `map` | "cube", "sphere" | "cube" | cube map, or a sphere (disk) map derived from it |
| `resolution` | int in [4, 4096] | 256 | texels per cube face side / sphere map side |
| `filter` | "nearest", "bilinear" | "bilinear" | texel filter (clamped at face edges) |
| `parallax` | "none", "box" | "box" | "box": intersect r with a proxy box first |
| `proxy_min`, `proxy_max` | xyz | room bounds | the proxy box (default: `room` objects) |
| `capture_offset` | float >= 0.0 | 0.05 | planar mirrors: capture point in front of the center |
| `capture` | {mirror = xyz} | {} | capture point per mirror name (default: the center) |
| `update` | "once", "every", int >= 1 | "once" | capture at frame 0, every frame, or every N |
| `faces_per_frame` | int in [1, 6] | 6 | cube faces refreshed per update (1 to 6, round robin) |

The classic fast approximation (lecture notes; Bastos & Stuerzlinger sec. 3): the map is
captured once from one point with the reflector itself left out, assuming the environment
is distant; each mirror pixel looks up r = 2 n (n.v) - v. Objects near the reflector show
the known parallax error; `parallax = "box"` removes it for surfaces on the proxy box.
Maps are captured at frame 0 (moving objects are not followed: a warning says so) unless
`update` asks for recaptures every N frames or every frame; `faces_per_frame` time-slices
cube maps (each update refreshes that many faces, round robin; sphere maps need all six,
reflectcli/maps/update.py). Maps are cached on disk by a hash of the scene's content, the
capture point, the capture frame and the map parameters (`reflect precompute-maps`).
"""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, Field, model_validator

from ...config.base import Strict, UpdatePolicy, Vec3, described


class EnvmapParams(Strict):
    model_config = ConfigDict(title="envmap")

    name: Literal["envmap"] = "envmap"
    map: Literal["cube", "sphere"] = "cube"
    resolution: int = Field(default=256, ge=4, le=4096)
    filter: Literal["nearest", "bilinear"] = "bilinear"
    parallax: Literal["none", "box"] = "box"
    proxy_min: Vec3 | None = None
    proxy_max: Vec3 | None = None
    capture_offset: float = Field(default=0.05, ge=0.0)
    capture: dict[str, Vec3] = Field(default_factory=dict)
    update: UpdatePolicy = "once"
    faces_per_frame: int = Field(default=6, ge=1, le=6)

    @model_validator(mode="after")
    def _slices_cube_maps_only(self) -> EnvmapParams:
        if self.map == "sphere" and self.faces_per_frame != 6:
            raise ValueError("faces_per_frame < 6 needs map = \"cube\" (a sphere map is made "
                             "from all six faces)")
        return self


Params = described(EnvmapParams, __doc__)
