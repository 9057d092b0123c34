"""Which method finds a reflector's virtual vertices, and the reflector's parts with their
vertex functions: exact mirroring for planar mirrors, the exact sphere and extrusion
searches for their shapes, explosion maps (one per convex / concave / crease part) for
other meshes."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Literal, Protocol

import numpy as np

from ..camera import Camera
from ..geometry import reflect_point
from ..raster.primary import Primary
from ..raster.rasterize import RasterWorkspace
from ..raster.rasterize.buffers import scratch
from ..raster.rasterize.passes import MAX_PASSES
from ..scene.types import CYLINDER, PLANAR, SPHERE, Mirrors, Scene
from .circle import cylinder_virtual_vertices, sphere_virtual_vertices
from .compose import part_stencil
from .direct import profile_virtual_vertices
from .part import ExplosionPart
from .partpasses import label_parts
from .partsetup import parts_extents, parts_foci
from .shape import ShapeCache
from .view import ViewCache

Method = Literal["planar", "sphere", "extrusion", "explosion"]
# points (N, 3) world [, polygons (T, 3) point indices] -> (virtual points (N, 3) world,
# flags (N,): hidden or not exactly reflected)
VertexFn = Callable[..., tuple[np.ndarray, np.ndarray]]


class ExplosionRule(Protocol):
    """The technique's `explosion` Params."""

    resolution: int
    near_scale: float
    layers: int
    center: str
    refine: str


class MethodRule(Protocol):
    """The technique's Params, as far as choosing methods and parts goes."""

    method: str
    decompose: str
    decompose_overrides: dict[str, str]
    explosion: ExplosionRule


def choose_method(requested: str, kind: int, profiled: bool) -> Method:
    """The method for a mirror of `kind` (`profiled`: an extrusion with a known profile):
    `requested` where the mirror has its shape, else explosion maps."""
    if kind == PLANAR:
        return "planar"
    extrusion = kind == CYLINDER or profiled
    if requested == "auto":
        return "sphere" if kind == SPHERE else "extrusion" if extrusion else "explosion"
    if (requested == "sphere" and kind != SPHERE) or (requested == "extrusion"
                                                      and not extrusion):
        return "explosion"  # the direct methods need their shape; fall back
    return requested  # type: ignore[return-value]


def facing_plane(mirrors: Mirrors, k: int, eye: np.ndarray) -> tuple[np.ndarray, float]:
    """Planar mirror k's (n, d) (world), signed so that the eye is on its positive side."""
    n, d = mirrors.plane(k)
    if n @ eye + d < 0:
        n, d = -n, -d
    return n, d


def reflector_parts(rule: MethodRule, scene: Scene, primary: Primary, k: int, camera: Camera,
                    scene_points: np.ndarray, shapes: ShapeCache, views: ViewCache,
                    ws: RasterWorkspace | None = None) -> Iterator[tuple[np.ndarray, VertexFn]]:
    """(stencil (H, W) screen, vertex function) for each part of reflector k seen in
    `primary`. Explosion parts build their maps when reached (this is a generator).
    `ws`: where the stencils are kept across calls (each written whole; valid until the
    next call)."""
    sid = scene.n_objects + k
    kind = int(scene.mirrors.kind[k])
    eye = np.asarray(camera.eye, np.float64)
    method = choose_method(rule.method, kind, k in scene.mirror_profiles)
    if method == "explosion":
        yield from explosion_parts(rule, scene, primary, k, camera, scene_points, shapes,
                                   views, ws)
        return
    surface = primary.frame.surface
    stencil_all = np.equal(surface, sid,
                           out=scratch(ws, "reflector_stencil", surface.shape, np.bool_))
    if method == "planar":
        n, d = facing_plane(scene.mirrors, k, eye)
        # points on or behind the plane (a wall the mirror hangs on) are not reflected:
        # they count as hidden, and draw_virtual clips virtual geometry to behind the plane
        yield stencil_all, lambda pts, _=None: (reflect_point(pts, n, d), pts @ n + d <= 0.0)
        return
    if method == "sphere":
        center, radius = scene.mirrors.sphere(k)
        yield stencil_all, lambda pts, _=None: sphere_virtual_vertices(pts, eye, center, radius)
        return
    if method == "extrusion" and kind == CYLINDER:
        origin, axis, radius, _height = scene.mirrors.cylinder(k)
        yield stencil_all, lambda pts, _=None: cylinder_virtual_vertices(
            pts, eye, origin, axis, radius)
        return
    if method == "extrusion":
        profile, normals, world_from_local, _ = scene.mirror_profiles[k]
        yield stencil_all, lambda pts, _=None: profile_virtual_vertices(
            pts, eye, profile, normals, world_from_local)


def explosion_parts(rule: MethodRule, scene: Scene, primary: Primary, k: int, camera: Camera,
                    scene_points: np.ndarray, shapes: ShapeCache,
                    views: ViewCache, ws: RasterWorkspace | None = None
                    ) -> Iterator[tuple[np.ndarray, ExplosionPart]]:
    """Mesh reflector k split into parts (unless `decompose` says no), each with its
    explosion maps, stencil restricted to the part's faces. `ws`: where each part's stencil
    is kept across calls (one array a part: a caller may hold them all at once)."""
    sid = scene.n_objects + k
    reflector = _explosion_reflector(rule, scene, primary, k, camera, shapes, views)
    first, count, shape, view = reflector[:4]
    for p, (part, part_view) in enumerate(zip(shape.parts, view.parts, strict=True)):
        # the part's pixels: the reflector's, with a face of the part under them
        in_part = np.zeros(count + 1, bool)
        in_part[part.faces] = True
        # (part_stencil writes every pixel)
        stencil = scratch(ws, f"explosion_stencil_{p}", primary.frame.surface.shape, np.bool_)
        part_stencil(primary.buffers.triangle, primary.frame.surface, sid, first, in_part,
                     stencil)
        if not stencil.any():
            continue
        yield stencil, _explosion_part(rule, camera, scene_points, reflector, part, part_view)


def explosion_group(rule: MethodRule, scene: Scene, primary: Primary, k: int, camera: Camera,
                    scene_points: np.ndarray, shapes: ShapeCache, views: ViewCache,
                    box: tuple[int, int, int, int], ws: RasterWorkspace):
    """explosion_parts' parts of mesh reflector k (those with pixels, in order) for their
    passes drawn together (partpasses.py): (parts, label_parts' (labels, stencil, floor,
    boxes) with part p's pixels labelled p + 1), no stencil of their own; None for a
    reflector of one part, or of more than MAX_PASSES. `box`: the reflector's pixels'."""
    sid = scene.n_objects + k
    reflector = _explosion_reflector(rule, scene, primary, k, camera, shapes, views)
    first, count, shape, view = reflector[:4]
    if not 1 < len(shape.parts) <= MAX_PASSES:
        return None
    label_of = np.zeros(count + 1, np.uint8)  # reflector face -> its part's label
    for p, part in enumerate(shape.parts):
        label_of[part.faces] = p + 1
    labelled = label_parts(primary, sid, first, label_of, box, ws)
    seen = [p for p in range(len(shape.parts)) if labelled[3][p, 1] > 0]
    if len(seen) < len(shape.parts):  # parts with no pixels are left out: labels anew
        label_of[:] = 0
        for j, p in enumerate(seen):
            label_of[shape.parts[p].faces] = j + 1
        labelled = label_parts(primary, sid, first, label_of, box, ws)
    if len(seen) < 2:
        return None  # drawn as one part
    # every part's focus, extent and screen positions in one kernel call each (partsetup.py)
    joined = shape.joined
    chosen = np.array(seen, np.int64)
    meshes = [shape.parts[p].mesh for p in seen]
    if rule.explosion.center == "focus":
        centres = parts_foci(joined, chosen, meshes, camera.eye)
    else:
        centres = [mesh.vertices.mean(axis=0) for mesh in meshes]
    extents = parts_extents(joined, chosen, np.array(centres, np.float64),
                            np.array([shape.parts[p].concave for p in seen]), scene_points,
                            camera.eye, reflector[4], camera.width, camera.height)
    parts = [_explosion_part(rule, camera, scene_points, reflector, shape.parts[p],
                             view.parts[p], centre, extent, (joined, p))
             for p, centre, extent in zip(seen, centres, extents, strict=True)]
    return parts, labelled


def _explosion_reflector(rule: MethodRule, scene: Scene, primary: Primary, k: int,
                         camera: Camera, shapes: ShapeCache, views: ViewCache) -> tuple:
    """(first soup triangle, face count, shape, view, clip_from_world) of mesh reflector
    k."""
    sid = scene.n_objects + k
    tris = primary.triangles
    first = int(np.flatnonzero(tris.surface == sid)[0])  # the reflector's triangles are
    count = int(np.count_nonzero(tris.surface == sid))  # contiguous in the soup
    corners = tris.corners[first:first + count]
    normals = tris.normals[first:first + count]
    mode = rule.decompose_overrides.get(scene.mirrors.names[k], rule.decompose)
    soup = shapes.soup_key(tris.corners, tris.normals, first, count)
    shape = shapes.get(soup, corners, normals, mode == "auto")
    clip_from_world = primary.buffers.clip_from_world  # the camera's, as the primary drew
    view = views.get((soup, mode == "auto"), corners, normals, shape, camera, clip_from_world,
                     rule.explosion.refine == "screen")
    return first, count, shape, view, clip_from_world


def _explosion_part(rule: MethodRule, camera: Camera, scene_points: np.ndarray,
                    reflector: tuple, part, part_view, focus: np.ndarray | None = None,
                    extent: tuple | None = None,
                    together: tuple | None = None) -> ExplosionPart:
    """One part's ExplosionPart (reflector: _explosion_reflector's; focus: its ray_focus,
    or the centre its `center` rule gives, if made; extent, together: ExplosionPart's)."""
    view, clip_from_world = reflector[3], reflector[4]
    params = rule.explosion
    return ExplosionPart(part, part_view, view.depth, view.grid, camera, clip_from_world,
                         scene_points, params.center, params.near_scale, params.resolution,
                         params.layers, focus, extent, together)
