"""The virtual-objects technique: per reflector seen, its parts' virtual vertices
(reflectcli/virtual/dispatch.py), the virtual objects drawn over its pixels
(reflectcli/virtual/raster.py) and blended with its reflectance.

Shading: each virtual fragment is shaded as the ray tracer shades the same hit, seen along
the eye ray reflected at the reflector point under its pixel (two-sided lambert turns the
normal toward that ray; from the real eye, a floor mirror's view of an underside was lit as
the top side, up to 3.5x too bright).

Known limits (measured at the bundled scenes' resolution, frame 0, unlit):
- concave-mirror: 80 of 63,426 dish pixels along the top rim stay bare (the mirror's base
  color where the ray tracer sees the room). Reflection points there lie within a pixel of
  the rim; the scene points beyond have no reflection point on the cap at all, so the
  triangles that span the rim have vertices without an exact virtual vertex and end short
  of it. This is the method's boundary problem (the paper extends its explosion maps past
  the boundary for the same reason); one-pixel cracks elsewhere are closed by
  `fill_cracks`.
- mask: 3,990 of 60,222 mirror pixels in wedges along the creases between its convex and
  concave parts stay bare. Each part gets one image with one virtual vertex per scene
  point; near a crease a scene point's reflection point lies in the neighbouring part (or
  in both), so the triangles whose reflection straddles the crease belong to neither image.
  Drawing each triangle in every part its vertices reflect in would need the per-part
  vertex functions to answer for points outside their part; not done.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from ...camera import Camera
from ...frame import Frame
from ...raster.rasterize import RasterWorkspace
from ...raster.shade import add_reflection
from ...scene.types import PLANAR, UNLIT, Geometry, Scene
from ...virtual.compose import gather_corners
from ...virtual.dispatch import choose_method, explosion_group, facing_plane, reflector_parts
from ...virtual.partpasses import PartPassCache, draw_parts
from ...virtual.parts import parts_vertices
from ...virtual.primary import primary_and_boxes
from ...virtual.raster import draw_virtual, reflected_rays
from ...virtual.reflected import ReflectedCache, pieces_holding_eye
from ...virtual.shape import ShapeCache
from ...virtual.together import (
    TogetherCache,
    draw_spheres,
    labels_buffers,
    sphere_labels,
    spheres_vertices,
    worth_together,
)
from ...virtual.view import ViewCache
from ..base import Technique
from . import Params


@dataclass
class VirtualState:
    """What frames share: tessellations, reflector shapes and views, each cached by what
    decides it."""

    scene: Scene
    reflected: ReflectedCache = field(default_factory=ReflectedCache)
    shapes: ShapeCache = field(default_factory=ShapeCache)
    views: ViewCache = field(default_factory=ViewCache)
    together: TogetherCache = field(default_factory=TogetherCache)
    part_passes: PartPassCache = field(default_factory=PartPassCache)
    # label p + 1 of the p-th mirror drawn with the sphere mirrors (together.py), set by
    # the primary pass (the labels of a frame that sees all of them)
    sphere_labels: np.ndarray = field(default_factory=lambda: np.zeros(0, np.uint8))
    together_ok: tuple[bool, ...] = ()  # per mirror: drawn with the sphere mirrors if seen
    # the rasterizer's scratch of the primary pass (its outputs stay the frame's own), and
    # the virtual passes' buffers, consumed per part: kept across frames, not allocated anew
    primary_raster: RasterWorkspace = field(default_factory=RasterWorkspace)
    virtual_raster: RasterWorkspace = field(
        default_factory=lambda: RasterWorkspace(outputs=True))

    @cached_property
    def scene_points(self) -> np.ndarray:
        """(N, 3) world: the corners at frame 0 the far explosion map must bound, reduced to
        their convex hull's vertices (one-time work: a part measured its distance to every
        corner per frame, and the farthest corner from any point is a hull vertex)."""
        points = self.scene.geometry(0).all_triangles().corners.reshape(-1, 3)
        try:
            return points[ConvexHull(points).vertices]
        except (QhullError, ValueError):  # flat or too few points: all of them
            return points


class Virtual(Technique):
    name = "virtual"
    Params = Params

    def prepare(self, scene: Scene) -> VirtualState:
        """One-time work, kept out of frame time: at frame 0, what every reflector reflects
        tessellated (for an eye outside every closed piece; `prepare_first_view` adds those
        of the first frame's eye if it is inside one), and each mesh reflector's shape
        (welded, decomposed into parts, boundary edges); both are cached and reused while
        the geometry does not change."""
        state = VirtualState(scene)
        state.sphere_labels = sphere_labels(scene, lambda k: self._together(scene, k))
        state.together_ok = tuple(self._together(scene, k) for k in range(scene.mirrors.count))
        geometry = scene.geometry(0)
        tris = geometry.all_triangles()
        explosion = False
        for k in self._tessellated(state, geometry, ()):
            mine = np.flatnonzero(tris.surface == scene.n_objects + k)
            first, count = int(mine[0]), int(mine.size)  # a reflector's triangles are contiguous
            corners = tris.corners[first:first + count]
            normals = tris.normals[first:first + count]
            mode = self.params.decompose_overrides.get(scene.mirrors.names[k],
                                                       self.params.decompose)
            soup = state.shapes.soup_key(tris.corners, tris.normals, first, count)
            state.shapes.get(soup, corners, normals, mode == "auto")
            explosion = True
        if explosion:
            _ = state.scene_points  # the far maps' bound, made here rather than in frame 0
        return state

    def prepare_first_view(self, state: VirtualState, camera: Camera) -> None:
        """The tessellations frame 0 asks for when its eye is inside a closed piece's box
        (cylinder-room: the room), whose faces may not be left out: made here, not in
        frame 0's time."""
        geometry = state.scene.geometry(0)
        inside = pieces_holding_eye(geometry, camera)
        if inside:
            self._tessellated(state, geometry, inside)

    def _tessellated(self, state: VirtualState, geometry: Geometry,
                     inside: tuple[int, ...]) -> list[int]:
        """Every reflector's reflected objects tessellated for an eye inside the pieces
        `inside` (ReflectedCache.get, welded: for the vertex functions of one point at a
        time); the explosion reflectors' indices."""
        scene = state.scene
        surface = geometry.all_triangles().surface
        explosion = []
        for k in range(scene.mirrors.count):
            if not np.any(surface == scene.n_objects + k):
                continue  # a reflector with no triangles is never seen (render skips it too)
            method = self._method(scene, k)
            state.reflected.get(geometry, scene.n_objects, k, self.params.tessellation,
                                exact=method != "explosion", weld=True, inside=inside)
            if method == "explosion":
                explosion.append(k)
        return explosion

    def _method(self, scene: Scene, k: int) -> str:
        """Mirror k's vertex method (dispatch.choose_method)."""
        return choose_method(self.params.method, int(scene.mirrors.kind[k]),
                             k in scene.mirror_profiles)

    def _together(self, scene: Scene, k: int) -> bool:
        """Whether mirror k, when seen, is drawn with the other sphere mirrors."""
        return (self.params.reflector_test != "clip_planes"
                and self._method(scene, k) == "sphere")

    def forget_view(self, state: VirtualState) -> None:
        state.views.forget()  # hidden maps, ray grids and tiles belong to one view

    def render(self, state: VirtualState, frame_index: int, camera: Camera) -> Frame:
        """Stages (seconds in the frame's timings): the primary pass (`rasterize`, `shade`),
        `tessellate` (cached lookups), `maps` (a part's explosion maps, and the reflector's
        view when first needed), `virtual_vertices`, `virtual_raster` (reflected rays,
        virtual passes, blending) and `glue`: the rest of the frame (geometry lookup, the
        primary frame's masks, loop overhead), so that the stages add up to the frame."""
        t_frame = time.perf_counter()
        scene = state.scene
        # the primary pass and which mirrors are in view, with the box of each one's pixels
        labels, stencil = labels_buffers(state.virtual_raster, camera.height, camera.width)
        primary, counts, boxes, labelled = primary_and_boxes(
            scene, frame_index, camera, state.primary_raster, state.sphere_labels, labels,
            stencil)
        result = primary.frame
        geometry = scene.geometry(frame_index)
        clip_from_world = primary.buffers.clip_from_world  # the camera's (85 us to make)
        # the closed pieces holding the eye: faces of theirs are never dropped
        inside = pieces_holding_eye(geometry, camera, state.virtual_raster)
        stats = {"virtual_vertices": 0, "virtual_triangles": 0, "reflector_parts": 0}
        seconds = dict.fromkeys(("tessellate", "maps", "virtual_vertices", "virtual_raster"),
                                0.0)
        t_start = time.perf_counter()
        seen = np.flatnonzero(counts)
        incoming = None  # per pixel, the reflected ray shading sees its fragment along
        # (lit shading only: unlit shading reads the albedo alone, so the rays, 0.8 ms of
        # four-spheres' frame at 1 thread, would go unread)
        if seen.size and scene.shading != UNLIT:
            box = (int(boxes[seen, 0].min()), int(boxes[seen, 1].max()),
                   int(boxes[seen, 2].min()), int(boxes[seen, 3].max()))
            incoming = reflected_rays(primary, camera.eye, box, state.virtual_raster)
        seconds["virtual_raster"] += time.perf_counter() - t_start
        ws = state.virtual_raster
        # sphere mirrors drawn together (virtual/together.py): the same bytes, in 3
        # parallel regions for all of them instead of 5 each
        together = [k for k in seen.tolist() if state.together_ok[k]]
        if together and worth_together(boxes[together]):
            t_start = time.perf_counter()
            parts = tuple(state.reflected.get(geometry, scene.n_objects, k,
                                              self.params.tessellation, exact=True,
                                              inside=inside)
                          for k in together)
            group = state.together.get(tuple(together), parts)
            t0 = time.perf_counter()
            virtual, hidden = spheres_vertices(scene, camera.eye, group, state.together, ws)
            t1 = time.perf_counter()
            draw_spheres(scene, primary, camera.eye, clip_from_world, group, virtual, hidden,
                         boxes[together], self.params.reflector_test == "zbuffer", incoming,
                         ws, state.sphere_labels if labelled else None)
            seconds["tessellate"] += t0 - t_start
            seconds["virtual_vertices"] += t1 - t0
            seconds["virtual_raster"] += time.perf_counter() - t1
            stats["virtual_vertices"] += sum(t.points.shape[0] for t in parts)
            stats["virtual_triangles"] += sum(t.triangles.count for t in parts)
            stats["reflector_parts"] += len(parts)
            seen = [k for k in seen if int(k) not in together]
        for k in (int(k) for k in seen):
            box = tuple(int(v) for v in boxes[k])
            t_start = time.perf_counter()
            method = self._method(scene, k)
            # an explosion reflector's points cost far more than welding them (14 parts'
            # maps and refinement; the mask's: 2 ms to weld, 30 saved): a tessellation
            # made in a frame (moving geometry, an eye inside a piece) is welded too
            tess = state.reflected.get(geometry, scene.n_objects, k, self.params.tessellation,
                                       weld=method == "explosion", inside=inside,
                                       exact=method != "explosion")
            seconds["tessellate"] += time.perf_counter() - t_start
            mirror_plane = None
            if scene.mirrors.kind[k] == PLANAR:
                mirror_plane = np.append(*facing_plane(scene.mirrors, k, camera.eye))
            t_start = time.perf_counter()
            group = None
            if self.params.reflector_test != "clip_planes" and method == "explosion":
                group = explosion_group(self.params, scene, primary, k, camera,
                                        state.scene_points, state.shapes, state.views, box,
                                        ws)
            if group is not None:
                # several parts: each stage for all of them at once (virtual/parts.py),
                # their passes drawn together (virtual/partpasses.py); the same bytes
                seconds["maps"] += time.perf_counter() - t_start
                explosion, labelled = group
                t0 = time.perf_counter()
                # float32: what the draw's gather reads (one signature of its kernel)
                virtual, hidden = parts_vertices(explosion, tess.points, tess.corner_index,
                                                 ws, np.float32)
                t1 = time.perf_counter()
                draw_parts(scene, primary, camera.eye, clip_from_world, k, tess,
                           state.part_passes.get(tess, len(explosion)), labelled, virtual,
                           hidden, box, self.params.reflector_test == "zbuffer", incoming, ws)
                seconds["virtual_vertices"] += t1 - t0
                seconds["virtual_raster"] += time.perf_counter() - t1
                stats["virtual_vertices"] += tess.points.shape[0] * len(explosion)
                stats["virtual_triangles"] += tess.triangles.count * len(explosion)
                stats["reflector_parts"] += len(explosion)
                continue
            # a reflector's parts, each with its vertex function (an explosion part's maps
            # are built when its points are known, in the vertex functions)
            parts = list(reflector_parts(self.params, scene, primary, k, camera,
                                         state.scene_points, state.shapes, state.views, ws))
            seconds["maps"] += time.perf_counter() - t_start
            for stencil, vertices_of in parts:
                t0 = time.perf_counter()
                virtual, hidden = vertices_of(tess.points, tess.corner_index)
                t1 = time.perf_counter()
                # corners gathered in float32 (what the rasterizer takes): half the bytes;
                # polygons wholly in the hidden region are not reflected (the paper drops
                # them); mixed ones keep their doubly virtual vertices
                count = tess.triangles.count
                corners = ws.get("virtual_corners", (count, 3, 3), np.float32)
                flags = ws.get("virtual_flags", (count,), np.uint8)
                gather_corners(virtual, hidden, tess.corner_index, tess.triangles.surface,
                               scene.n_objects, corners, flags)
                colors = draw_virtual(scene, primary, camera, clip_from_world, tess.triangles,
                                      corners, flags, stencil, box, scene.n_objects + k,
                                      mirror_plane, self.params.reflector_test, incoming, ws)
                add_reflection(result.rgb, colors, stencil, scene.mirrors.reflectance[k], *box)
                seconds["virtual_vertices"] += t1 - t0
                seconds["virtual_raster"] += time.perf_counter() - t1
                stats["virtual_vertices"] += tess.points.shape[0]
                stats["virtual_triangles"] += count
                stats["reflector_parts"] += 1
        result.timings.update(seconds)
        result.timings["glue"] = max(
            time.perf_counter() - t_frame - sum(result.timings.values()), 0.0)
        result.stats.update(stats)
        return result
