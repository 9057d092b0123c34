"""The multi-pass re-rendering technique class (parameters and method: the package
docstring)."""

from __future__ import annotations

import time

import numpy as np

from ...camera import Camera, reflection_pass_matrices
from ...frame import Frame
from ...geometry import reflection_matrix
from ...raster.closed import reflection_pass_flags
from ...raster.primary import render_primary
from ...raster.rasterize import RasterWorkspace, rasterize
from ...raster.shade import add_reflection, shade_buffers
from ...scene.types import PLANAR, Geometry, Scene
from ..base import Technique, warn_non_planar
from . import RerenderParams


class Rerender(Technique):
    name = "rerender"
    Params = RerenderParams
    _primary_ws: RasterWorkspace | None = None
    _pass_ws: RasterWorkspace | None = None
    _levels: dict[int, tuple[np.ndarray, np.ndarray]]

    def prepare(self, scene: Scene) -> Scene:
        warn_non_planar(scene, "rerender")
        # rasterizer scratch kept across frames (the primary pass's triangle ids too: read
        # only while the frame renders); reflection passes' buffers are shaded at once
        self._primary_ws = RasterWorkspace(ids=True)
        self._pass_ws = RasterWorkspace(outputs=True)
        self._levels = {}
        return scene

    def _level_arrays(self, level: int,
                      shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """rgb, surface and stencil arrays of a reflection level's passes, kept across frames
        (a level's passes run one after another; deeper levels, which read this level's
        stencil as their mask, have their own)."""
        kept = self._levels.get(level)
        if kept is None or kept[1].shape != shape:
            kept = (np.empty((*shape, 3), np.float32), np.empty(shape, np.int32),
                    np.empty(shape, np.bool_))
            self._levels[level] = kept
        return kept

    def render(self, scene: Scene, frame_index: int, camera: Camera) -> Frame:
        if self._pass_ws is None:
            self.prepare(scene)
        primary = render_primary(scene, frame_index, camera, self._primary_ws)
        result = primary.frame
        stats = {"passes": 1, "triangles_rasterized": primary.triangles.count,
                 "pass_seconds": []}
        self._reflect(scene, primary.geometry, primary.flags, camera, 1, np.eye(4),
                      camera.eye, result.surface, None, result.rgb, stats)
        result.timings["reflections"] = sum(stats["pass_seconds"])
        result.stats.update(stats)
        return result

    def _reflect(self, scene, geometry: Geometry, flags, camera, level, chain, eye, surface,
                 mask, rgb, stats) -> None:
        """Fill the mirror pixels of `rgb` (inside `mask`; None: everywhere) seen from `eye`
        at this level."""
        if level > self.params.max_depth:
            return
        tris = geometry.all_triangles()
        mirrors = scene.mirrors
        out_rgb, out_surface, stencil = self._level_arrays(level, surface.shape)
        for k in range(mirrors.count):
            if mirrors.kind[k] != PLANAR:
                continue
            sid = scene.n_objects + k
            # written whole for each mirror (the level's kept array)
            np.equal(surface, sid, out=stencil)
            if mask is not None:
                stencil &= mask
            if not stencil.any():
                continue
            start = time.perf_counter()
            n, d = mirrors.plane(k)
            if n @ eye + d < 0:  # mirrors are two-sided: face the plane toward this eye
                n, d = -n, -d
            reflect = reflection_matrix(n, d)
            new_chain = chain @ reflect
            new_eye = (reflect @ np.append(eye, 1.0))[:3]
            # the kept side starts just behind the mirror: a wall the mirror hangs on (coplanar
            # with it) must not be drawn over the reflection (the ray tracer likewise starts
            # reflected rays a little off the surface)
            offset = 1e-4 * (1.0 + abs(d) + float(np.abs(eye).max()))
            clip_plane = np.append(n, d - offset)
            clip_from_world, planes = reflection_pass_matrices(
                camera, new_chain, clip_plane, self.params.clip)
            # the mirror itself left out; closed pieces seen from outside by the reflected
            # eye, whole on one side of the clip plane, drawn without their far faces
            pass_flags = reflection_pass_flags(geometry, flags, sid, new_eye, clip_plane,
                                               camera, level, self._pass_ws)
            buffers = rasterize(tris.corners, pass_flags, clip_from_world, camera.width,
                                camera.height, planes, mask=stencil, workspace=self._pass_ws)
            # only the stencil's pixels are shaded (and read below): the rest of the pass's
            # buffers is never looked at
            reflected, reflected_surface = shade_buffers(
                buffers, tris, scene, new_eye, stencil=stencil,
                out=(out_rgb, out_surface))
            stats["passes"] += 1
            stats["triangles_rasterized"] += tris.count
            stats["pass_seconds"].append(time.perf_counter() - start)
            self._reflect(scene, geometry, flags, camera, level + 1, new_chain, new_eye,
                          reflected_surface, stencil, reflected, stats)
            # over the stencil's box; the rest of `reflected` was never written
            rows = np.flatnonzero(stencil.any(axis=1))
            cols = np.flatnonzero(stencil.any(axis=0))
            add_reflection(rgb, reflected, stencil, mirrors.reflectance[k], rows[0],
                           rows[-1] + 1, cols[0], cols[-1] + 1)
