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

The classic fast approximation (lecture notes; Bastos & Stuerzlinger sec. 3): the map is
captured once from one point with the reflector itself left out, assuming the environment
is distant; each mirror pixel looks up r = 2 n (n.v) - v. Objects near the reflector show
the known parallax error; `parallax = "box"` removes it for surfaces on the proxy box.
Maps are captured at frame 0 (moving objects are not followed) and cached on disk by a hash
of the scene's content, the capture point and the map parameters (`reflect precompute-maps`).
"""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, Field

from ...config.base import Strict, Vec3, described


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


Params = described(EnvmapParams, __doc__)
