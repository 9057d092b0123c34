"""Planar mirrors by re-rendering the scene through each mirror's reflection matrix.

| parameter | type | default | meaning |
|---|---|---|---|
| `max_depth` | int >= 0 | 1 | mirror-in-mirror levels; beyond, a mirror shows (1 - r) * base |
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

import time
from typing import Literal

import numpy as np
from pydantic import ConfigDict, Field

from ..camera import Camera
from ..config.base import Strict
from ..frame import Frame
from ..geometry import far_plane_clip, oblique_projection, reflection_matrix, transform_plane
from ..raster.primary import render_primary
from ..raster.rasterize import FLAG_SKIP, rasterize, standard_planes
from ..raster.shade import shade_buffers
from ..scene.types import PLANAR, Scene, Triangles
from .base import Technique, warn_non_planar


class RerenderParams(Strict):
    model_config = ConfigDict(title="rerender")

    name: Literal["rerender"] = "rerender"
    max_depth: int = Field(default=1, ge=0, le=16, description="mirror-in-mirror levels")
    clip: Literal["oblique", "plane", "none"] = Field(
        default="oblique", description="removal of geometry behind the mirror"
    )


def reflection_pass_matrices(
    camera: Camera, chain: np.ndarray, plane: np.ndarray, clip: str
) -> tuple[np.ndarray, np.ndarray]:
    """(world -> clip matrix, clip-space planes) of one reflection pass.

    `chain` is the product of reflection matrices (world -> virtual world), `plane` (4,) the
    mirror plane in world space oriented so that kept points (in front of the mirror, seen
    from the previous level's eye) are >= 0.
    """
    view = camera.view_matrix() @ chain
    proj = camera.projection_matrix()
    if clip == "oblique":
        proj = oblique_projection(proj, transform_plane(plane, view))
        # near plane = mirror plane; clip far against the original far plane, not the tilted one
        planes = np.array([[0.0, 0.0, 1.0, 1.0], far_plane_clip(proj, camera.far)])
        return proj @ view, planes
    world_to_clip = proj @ view
    if clip == "plane":
        extra = transform_plane(plane, world_to_clip)
        return world_to_clip, np.vstack([standard_planes(), extra / np.abs(extra).max()])
    return world_to_clip, standard_planes()


class Rerender(Technique):
    name = "rerender"
    Params = RerenderParams

    def prepare(self, scene: Scene) -> Scene:
        warn_non_planar(scene, "rerender")
        return scene

    def render(self, scene: Scene, frame: int, camera: Camera) -> Frame:
        primary = render_primary(scene, frame, camera)
        result = primary.frame
        stats = {"passes": 1, "triangles_rasterized": primary.triangles.count,
                 "pass_seconds": []}
        mask = np.ones(result.surface.shape, bool)
        self._reflect(scene, primary.triangles, primary.flags, camera, 1, np.eye(4), camera.eye,
                      result.surface, mask, result.rgb, stats)
        result.timings["reflections"] = sum(stats["pass_seconds"])
        result.stats.update(stats)
        return result

    def _reflect(self, scene, tris: Triangles, flags, camera, level, chain, eye, surface, mask,
                 rgb, stats) -> None:
        """Fill the mirror pixels of `rgb` (inside `mask`) seen from `eye` at this level."""
        if level > self.params.max_depth:
            return
        mirrors = scene.mirrors
        for k in range(mirrors.count):
            if mirrors.kind[k] != PLANAR:
                continue
            sid = scene.n_objects + k
            stencil = mask & (surface == sid)
            if not stencil.any():
                continue
            start = time.perf_counter()
            n = mirrors.params[k, :3].astype(np.float64)
            d = float(mirrors.params[k, 3])
            if n @ eye + d < 0:  # mirrors are two-sided: face the plane toward this eye
                n, d = -n, -d
            reflect = reflection_matrix(n, d)
            new_chain = chain @ reflect
            new_eye = (reflect @ np.append(eye, 1.0))[:3]
            # the kept side starts just behind the mirror: a wall the mirror hangs on (coplanar
            # with it) must not be drawn over the reflection (the ray tracer likewise starts
            # reflected rays a little off the surface)
            offset = 1e-4 * (1.0 + abs(d) + float(np.abs(eye).max()))
            world_to_clip, planes = reflection_pass_matrices(
                camera, new_chain, np.append(n, d - offset), self.params.clip)
            pass_flags = flags | np.where(tris.surface == sid, FLAG_SKIP, 0).astype(np.uint8)
            buffers = rasterize(tris.corners, pass_flags, world_to_clip, camera.width,
                                camera.height, planes, mask=stencil)
            reflected, reflected_surface = shade_buffers(buffers, tris, scene, new_eye)
            stats["passes"] += 1
            stats["triangles_rasterized"] += tris.count
            stats["pass_seconds"].append(time.perf_counter() - start)
            self._reflect(scene, tris, flags, camera, level + 1, new_chain, new_eye,
                          reflected_surface, stencil, reflected, stats)
            rgb[stencil] += mirrors.reflectance[k] * reflected[stencil]
