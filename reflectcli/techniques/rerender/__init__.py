"""Planar mirrors by re-rendering the scene through each mirror's reflection matrix.

| parameter | type | default | meaning |
|---|---|---|---|
| `max_depth` | int in [0, 16] | 1 | mirror-in-mirror levels; beyond, mirrors show (1 - r) * base |
| `clip` | "oblique", "plane", "none" | "oblique" | how geometry behind the mirror is removed |

Per visible planar mirror k (the classic multi-pass method; Bastos & Stuerzlinger sec. 2 and
the planar-reflection report): reflect the view through R_k (world space; the virtual eye is
R_k * eye), rasterize the whole scene again restricted by a stencil to the pixels where the
previous level saw mirror k (the id buffer is the stencil), shade it with the virtual eye as
the viewpoint, and blend: final = (1 - r) * base + r * reflected. Recursion composes the
reflections: at level L the view is V @ R_k1 @ ... @ R_kL, the stencil nests.

Geometry between the virtual eye and the mirror plane (behind the mirror in the real scene)
must not show: `oblique` replaces the near plane by the mirror plane (Lengyel), `plane` clips
against the mirror plane as an extra clip plane, `none` shows the classic artefact.
A reflection flips handedness, so screen winding flips on odd levels: culling (if a material
ever asks for it) must swap back and front there. Only planar mirrors are re-rendered; curved
mirrors show (1 - r) * base.
"""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, Field

from ...config.base import Strict, described


class RerenderParams(Strict):
    model_config = ConfigDict(title="rerender")

    name: Literal["rerender"] = "rerender"
    max_depth: int = Field(default=1, ge=0, le=16)
    clip: Literal["oblique", "plane", "none"] = "oblique"


Params = described(RerenderParams, __doc__)
