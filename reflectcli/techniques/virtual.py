"""Curved mirrors by virtual objects (Ofek & Rappoport): each reflected scene vertex gets a
virtual vertex, and the virtual objects are rasterized like any others, masked by the
reflector's pixels and blended.

| parameter | type | default | meaning |
|---|---|---|---|
| `method` | "auto", "explosion", "sphere", "extrusion" | "auto" | how virtual vertices are found |
| `explosion.resolution` | int | 200 | explosion map side in texels |
| `explosion.near_scale` | float | 1.1 | near sphere radius / reflector bounding radius |
| `explosion.layers` | int | 6 | maps on spheres from near to far (2: the paper's pair) |
| `explosion.center` | "mean", "focus" | "focus" | map center: vertex mean, or rays' focus |
| `explosion.refine` | "screen", "none" | "screen" | refine map answers on the reflector's pixels |
| `tessellation.subdivisions` | int | 7 | each reflected triangle split n x n (paper: 7x7) |
| `tessellation.max_edge` | float | (unset) | and further until no edge is longer (world) |
| `tessellation.max_edge_radii` | float | 1.0 | the same in reflector radii, if no max_edge |
| `tessellation.min_edge_radii` | float | 0.05 | no split into edges shorter (reflector radii) |
| `reflector_test` | "none", "clip_planes", "zbuffer" | "zbuffer" | front-of-reflector test |
| `decompose` | "auto", "none" | "auto" | split mesh reflectors into convex and concave parts |
| `decompose_overrides` | {mirror = "auto" or "none"} | {} | per-mirror choice |

`auto` uses the exact sphere method for spheres, the extrusion method (a binary search in
the cross-section) for cylinders and extrusion mirrors (the TV of Fig. 17), exact
mirroring for planar mirrors (the special case), and explosion maps for other meshes.
Explosion maps (centered where the reflection rays come closest together, their focus, or
at the paper's vertex mean; near: a sphere `near_scale` times the reflector's bounding
radius from there; far: one bounding the scene) and the hidden map (an item buffer and
z-buffer of the reflector alone) are rebuilt per frame and part
(reflectcli/virtual/explosion.py); `explosion.refine = "screen"` then refines each map
answer on the reflector's own pixels, Gauss-Newton on the reflection law
(reflectcli/virtual/refine.py). Mixed reflectors are split into convex, concave and
crease parts (reflectcli/virtual/mesh.py: convexity_parts), one image per part.
Reflected objects are everything but the reflector, tessellated by `tessellation`; mirrors
among them show their base color (one level of recursion, as in the paper's figures).
`reflector_test`: `zbuffer` rejects virtual fragments at or in front of the reflector's own
depth (the paper's second z-buffer), `clip_planes` clips against the faces of the
reflector's bounding box that face the viewer, `none` leaves doubly virtual polygons be.
"""

from __future__ import annotations

import hashlib
import time
from typing import Literal

import numpy as np
from pydantic import ConfigDict, Field

from ..camera import Camera
from ..config.base import Strict
from ..frame import Frame
from ..geometry import reflect_point, transform_plane
from ..raster.primary import Primary, render_primary
from ..raster.rasterize import FLAG_MIRROR, FLAG_SKIP, rasterize, standard_planes
from ..raster.shade import shade_buffers
from ..scene.types import CYLINDER, PLANAR, SPHERE, Scene, Triangles
from ..virtual.direct import (
    cylinder_virtual_vertices,
    profile_virtual_vertices,
    sphere_virtual_vertices,
)
from ..virtual.explosion import build_explosion_maps, ray_focus, virtual_vertices
from ..virtual.mesh import (
    IndexedMesh,
    Tessellation,
    concatenate_tessellations,
    convexity_parts,
    tessellate,
    vertex_convexity,
    weld,
)
from ..virtual.refine import BOUNDARY, EXACT, NONE, PartTiles, refine_virtual, reflector_grid
from .base import Technique


class ExplosionParams(Strict):
    resolution: int = Field(default=200, ge=16, le=4096, description="map side, texels")
    near_scale: float = Field(default=1.1, gt=1.0, description="near sphere / bounding radius")
    layers: int = Field(default=6, ge=2, le=64, description="maps from near to far sphere")
    center: Literal["mean", "focus"] = Field(
        default="focus", description="map center: vertex mean or the reflection rays' focus")
    refine: Literal["screen", "none"] = Field(
        default="screen", description="refine map answers on the reflector's pixels")


class TessellationParams(Strict):
    subdivisions: int = Field(default=7, ge=1, le=64, description="n x n per triangle")
    max_edge: float | None = Field(default=None, gt=0, description="longest edge (world)")
    max_edge_radii: float | None = Field(
        default=1.0, gt=0, description="longest edge in reflector radii (if no max_edge)")
    min_edge_radii: float | None = Field(
        default=0.05, ge=0, description="no split into edges shorter, in reflector radii")


class VirtualParams(Strict):
    model_config = ConfigDict(title="virtual")

    name: Literal["virtual"] = "virtual"
    method: Literal["auto", "explosion", "sphere", "extrusion"] = Field(
        default="auto", description="virtual vertex method")
    explosion: ExplosionParams = Field(default_factory=ExplosionParams,
                                       description="explosion maps")
    tessellation: TessellationParams = Field(default_factory=TessellationParams,
                                             description="reflected objects")
    reflector_test: Literal["none", "clip_planes", "zbuffer"] = Field(
        default="zbuffer", description="virtual geometry in front of the reflector")
    decompose: Literal["auto", "none"] = Field(default="auto", description="convex parts")
    decompose_overrides: dict[str, Literal["auto", "none"]] = Field(
        default_factory=dict, description="per mirror")


class Virtual(Technique):
    name = "virtual"
    Params = VirtualParams

    def prepare(self, scene: Scene) -> dict:
        state = {"scene": scene, "tessellated": {}}
        # one-time work, kept out of frame time: at frame 0, what every reflector reflects
        # tessellated, and each mesh reflector's convex parts (both cached and reused while
        # the geometry does not change)
        geometry = scene.geometry(0)
        tris = geometry.all_triangles()
        for k in range(scene.mirrors.count):
            self._reflected(state, scene, geometry, k)
            method = self._method(int(scene.mirrors.kind[k]), k in scene.mirror_profiles)
            mode = self.params.decompose_overrides.get(scene.mirrors.names[k],
                                                       self.params.decompose)
            mine = np.flatnonzero(tris.surface == scene.n_objects + k)
            if method == "explosion" and mode == "auto" and mine.size:
                first, count = int(mine[0]), int(mine.size)
                self._decompose(weld(tris.corners[first:first + count],
                                     tris.normals[first:first + count]))
        return state

    def render(self, state: dict, frame: int, camera: Camera) -> Frame:
        scene: Scene = state["scene"]
        primary = render_primary(scene, frame, camera)
        result = primary.frame
        geometry = scene.geometry(frame)
        stats = {"virtual_vertices": 0, "virtual_triangles": 0, "reflector_parts": 0}
        t_vertices = t_raster = t_maps = t_tessellate = 0.0
        for k in range(scene.mirrors.count):
            sid = scene.n_objects + k
            in_view = result.surface == sid
            if not in_view.any():
                continue
            t_start = time.perf_counter()
            tess = self._reflected(state, scene, geometry, k)
            reflected = tess.triangles
            t_tessellate += time.perf_counter() - t_start
            parts = self._parts(scene, primary, k, camera)
            while True:
                t_start = time.perf_counter()  # building a part's maps happens in next()
                item = next(parts, None)
                t_maps += time.perf_counter() - t_start
                if item is None:
                    break
                stencil, virtual_fn = item
                t0 = time.perf_counter()
                points = tess.points
                virtual, hidden = virtual_fn(points, tess.corner_index)
                virtual = virtual[tess.corner_index]
                # polygons wholly in the hidden region are not reflected (the paper drops
                # them); mixed ones keep their doubly virtual vertices
                dropped = hidden[tess.corner_index].all(axis=1)
                t1 = time.perf_counter()
                colors = self._draw(scene, primary, camera, reflected, virtual, dropped,
                                    stencil, k)
                result.rgb[stencil] += scene.mirrors.reflectance[k] * colors[stencil]
                t_vertices += t1 - t0
                t_raster += time.perf_counter() - t1
                stats["virtual_vertices"] += points.shape[0]
                stats["virtual_triangles"] += reflected.count
                stats["reflector_parts"] += 1
        result.timings.update({"tessellate": t_tessellate, "maps": t_maps,
                               "virtual_vertices": t_vertices, "virtual_raster": t_raster})
        result.stats.update(stats)
        return result

    def _reflected(self, state: dict, scene: Scene, geometry, k: int) -> Tessellation:
        """Everything but reflector k, tessellated for it (cached per geometry state)."""
        t = self.params.tessellation
        sid = scene.n_objects + k
        pts = geometry.mirror_tris.corners[geometry.mirror_tris.surface == sid]
        pts = pts.reshape(-1, 3).astype(np.float64)
        radius = float(np.linalg.norm(pts - pts.mean(axis=0), axis=1).max())
        max_edge = t.max_edge
        if max_edge is None and t.max_edge_radii is not None:
            max_edge = t.max_edge_radii * radius
        # a fine mesh (a sphere of 48 segments) gains nothing from n x n more: its triangles
        # are split only as far as edges of min_edge_radii reflector radii
        min_edge = (t.min_edge_radii or 0.0) * radius
        key = (geometry.key, k, t.subdivisions, max_edge, min_edge)
        cache = state["tessellated"]
        if key not in cache:
            if len(cache) > 16:
                cache.clear()
            # objects are tessellated; other mirrors (seen with their base color only) are
            # already fine meshes and keep their triangles
            tris = geometry.all_triangles()
            parts = []
            for keep, n, edge in ((tris.surface < scene.n_objects, t.subdivisions, max_edge),
                                  ((tris.surface >= scene.n_objects) & (tris.surface != sid),
                                   1, None)):
                parts.append(tessellate(Triangles(*(a[keep] for a in (
                    tris.corners, tris.uvs, tris.normals, tris.material, tris.surface))),
                    n, edge, min_edge))
            cache[key] = concatenate_tessellations(parts)
        return cache[key]

    def _method(self, kind: int, profiled: bool) -> str:
        m = self.params.method
        if kind == PLANAR:
            return "planar"
        extrusion = kind == CYLINDER or profiled
        if m == "auto":
            return "sphere" if kind == SPHERE else "extrusion" if extrusion else "explosion"
        if (m == "sphere" and kind != SPHERE) or (m == "extrusion" and not extrusion):
            return "explosion"  # the direct methods need their shape; fall back
        return m

    def _parts(self, scene: Scene, primary: Primary, k: int, camera: Camera):
        """(stencil, points -> virtual points) for each part of reflector k."""
        sid = scene.n_objects + k
        kind = int(scene.mirrors.kind[k])
        p = scene.mirrors.params[k]
        eye = np.asarray(camera.eye, np.float64)
        method = self._method(kind, k in scene.mirror_profiles)
        stencil_all = primary.frame.surface == sid
        if method == "planar":
            n, d = p[:3].astype(np.float64), float(p[3])
            if n @ eye + d < 0:
                n, d = -n, -d
            # points on or behind the plane (a wall the mirror hangs on) are not reflected:
            # they count as hidden, and _draw clips virtual geometry to behind the plane
            yield stencil_all, lambda pts, _=None: (reflect_point(pts, n, d), pts @ n + d <= 0.0)
            return
        if method == "sphere":
            yield stencil_all, lambda pts, _=None: sphere_virtual_vertices(pts, eye, p[:3], p[3])
            return
        if method == "extrusion" and kind == CYLINDER:
            yield stencil_all, lambda pts, _=None: cylinder_virtual_vertices(
                pts, eye, p[:3], p[3:6], p[6])
            return
        if method == "extrusion":
            profile, normals, frame, _ = scene.mirror_profiles[k]
            yield stencil_all, lambda pts, _=None: profile_virtual_vertices(
                pts, eye, profile, normals, frame)
            return
        tris = primary.triangles
        first = int(np.flatnonzero(tris.surface == sid)[0])
        count = int(np.count_nonzero(tris.surface == sid))
        mesh = weld(tris.corners[first:first + count], tris.normals[first:first + count])
        name = scene.mirrors.names[k]
        mode = self.params.decompose_overrides.get(name, self.params.decompose)
        parts = self._decompose(mesh) if mode == "auto" else [np.arange(len(mesh.faces))]
        buffer_face = np.where(primary.buffers.triangle >= first,
                               primary.buffers.triangle - first, -1)
        buffer_face[buffer_face >= count] = -1
        scene_points = scene.geometry(0).all_triangles().corners.reshape(-1, 3)
        # the reflector's own z-buffer and item buffer (the paper's hidden map): the reflector
        # alone, so that what hides it in the scene does not hide points behind it
        alone = rasterize(tris.corners[first:first + count], np.zeros(count, np.uint8),
                          camera.projection_matrix() @ camera.view_matrix(), camera.width,
                          camera.height)
        grid = None
        if self.params.explosion.refine == "screen":
            grid = reflector_grid(alone.triangle, alone.b1, alone.b2,
                                  tris.corners[first:first + count],
                                  tris.normals[first:first + count], camera.eye)
        for faces in parts:
            part = _sub_mesh(mesh, faces)
            in_part = np.zeros(count + 1, bool)
            in_part[faces] = True
            stencil = stencil_all & in_part[buffer_face]
            if not stencil.any():
                continue
            yield stencil, self._explosion_fn(part, faces, count, camera, alone, scene_points,
                                              grid)

    def _decompose(self, mesh: IndexedMesh) -> list[np.ndarray]:
        """convexity_parts, kept per reflector shape: it depends on the mesh alone, and a
        reflector that does not deform keeps its parts from frame to frame."""
        key = hashlib.blake2b(mesh.vertices.tobytes() + mesh.normals.tobytes()
                              + mesh.faces.tobytes(), digest_size=16).hexdigest()
        cache = self.__dict__.setdefault("_parts_cache", {})
        if key not in cache:
            if len(cache) > 16:
                cache.clear()
            cache[key] = convexity_parts(mesh)
        return cache[key]

    def _explosion_fn(self, part: IndexedMesh, faces, count, camera, alone, scene_points,
                      grid=None):
        params = self.params.explosion
        center = (ray_focus(part, camera.eye) if params.center == "focus"
                  else part.vertices.mean(axis=0))
        bound = float(np.linalg.norm(part.vertices - center, axis=1).max())
        far = float(np.linalg.norm(scene_points - center, axis=1).max()) * 1.01
        near = max(bound * params.near_scale, 1e-6)
        maps = build_explosion_maps(part, camera.eye, center, near, max(far, near * 1.01),
                                    params.resolution, params.layers)
        flip = np.zeros(3)
        if vertex_convexity(part).mean() < 0 and maps.front.any():  # a concave part
            flip = part.normals[maps.front].mean(axis=0)
            flip /= max(np.linalg.norm(flip), 1e-30)
        # the hidden map: the reflector's item buffer, restricted to this part's faces
        local = np.full(count + 1, -1, np.int64)
        local[faces] = np.arange(len(faces))
        hidden_map = local[alone.triangle]
        depth = alone.depth
        world_to_clip = camera.projection_matrix() @ camera.view_matrix()
        screen = _project(part.vertices, world_to_clip, camera)[:, :2]
        inside = (hidden_map >= 0) if grid is not None else None

        tiles = PartTiles(inside, grid[0], grid[1]) if grid is not None else None

        def fn(points: np.ndarray, polygons: np.ndarray | None = None):
            """(virtual points, flags). With `polygons` (T, 3) point indices, points no
            ray of this part can reach are skipped (flagged, left in place) unless a polygon
            joins them to one it can: most points of a scene miss most parts of a mixed
            reflector."""
            n = len(points)
            todo = np.ones(n, bool)
            retry = None
            if tiles is not None:
                reach, retry = tiles.scan(points, grid[0], grid[1])
                if polygons is not None:
                    todo = reach.copy()
                    todo[polygons[reach[polygons].any(axis=1)].ravel()] = True
            virtual = points.astype(np.float64).copy()
            flags = np.ones(n, bool)
            if todo.any():
                virtual[todo], flags[todo] = self._part_vertices(
                    points[todo], world_to_clip, camera, depth, hidden_map, maps, screen, flip,
                    grid, inside, None if retry is None else retry[todo])
            return virtual, flags

        fn.maps = maps  # for tests and figures
        return fn

    @staticmethod
    def _part_vertices(points, world_to_clip, camera, depth, hidden_map, maps, screen, flip,
                       grid, inside, retry):
        """Virtual vertices of `points` on one part: explosion maps (hidden points through
        the hidden map), then the refinement on the part's pixels."""
        proj = _project(points, world_to_clip, camera)
        finite = np.isfinite(proj[:, 0]) & np.isfinite(proj[:, 1]) & (proj[:, 2] > 0)
        x = np.floor(np.where(finite, proj[:, 0], -1)).astype(np.int64)
        y = np.floor(np.where(finite, proj[:, 1], -1)).astype(np.int64)
        ok = finite & (x >= 0) & (y >= 0) & (x < camera.width) & (y < camera.height)
        face = np.full(len(points), -1, np.int64)
        xs, ys = x[ok], y[ok]
        behind = proj[ok, 2] > depth[ys, xs]
        face[np.flatnonzero(ok)[behind]] = hidden_map[ys[behind], xs[behind]]
        virtual, flags = virtual_vertices(maps, points, face, proj[:, :2].copy(), screen, flip)
        if grid is not None:
            # seeds: where the map's virtual vertices land on the screen (on the eye ray
            # through the reflection point the map found); hidden points too: one behind the
            # reflector may still be reflected near its silhouette; where no reflection is
            # found it keeps its doubly virtual vertex
            seeds = _project(virtual, world_to_clip, camera)[:, :2]
            refined, status = refine_virtual(points, seeds, inside, grid[0], grid[1],
                                             camera.eye, retry)
            found = status != NONE
            virtual[found] = refined[found]
            flags = (flags & (status != EXACT)) | (status == BOUNDARY)
        return virtual, flags

    def _draw(self, scene, primary, camera, reflected, virtual, dropped, stencil,
              k) -> np.ndarray:
        """Rasterize the virtual objects over `stencil`; colors from the original surfaces."""
        world_to_clip = camera.projection_matrix() @ camera.view_matrix()
        planes = standard_planes()
        floor = None
        if scene.mirrors.kind[k] == PLANAR:  # the exact case: the mirror plane clips
            n = scene.mirrors.params[k, :3].astype(np.float64)
            d = float(scene.mirrors.params[k, 3])
            if n @ camera.eye + d < 0:
                n, d = -n, -d
            offset = 1e-4 * (1.0 + abs(d) + float(np.abs(camera.eye).max()))
            clip = transform_plane(np.append(-n, -d - offset), world_to_clip)
            planes = np.vstack([planes, clip / np.abs(clip).max()])
        elif self.params.reflector_test == "zbuffer":
            floor = np.where(stencil, primary.buffers.depth, 0.0).astype(np.float32)
        elif self.params.reflector_test == "clip_planes":
            sid = scene.n_objects + k
            pts = primary.triangles.corners[primary.triangles.surface == sid].reshape(-1, 3)
            planes = np.vstack([planes, _box_planes(pts, camera.eye, world_to_clip)])
        flags = np.where(reflected.surface >= scene.n_objects, FLAG_MIRROR, 0).astype(np.uint8)
        flags[dropped] |= FLAG_SKIP
        buffers = rasterize(virtual.astype(np.float32), flags, world_to_clip, camera.width,
                            camera.height, planes, mask=stencil, depth_floor=floor)
        colors, _ = shade_buffers(buffers, reflected, scene, camera.eye)
        return colors


def _sub_mesh(mesh: IndexedMesh, faces: np.ndarray) -> IndexedMesh:
    used, inverse = np.unique(mesh.faces[faces].reshape(-1), return_inverse=True)
    return IndexedMesh(mesh.vertices[used], mesh.normals[used], inverse.reshape(-1, 3),
                       mesh.soup_index[faces])


def _project(points: np.ndarray, world_to_clip: np.ndarray, camera: Camera) -> np.ndarray:
    """(N, 3): screen x, y (pixels) and eye depth w (<= 0 behind the eye)."""
    h = points @ world_to_clip[:3, :3].T + world_to_clip[:3, 3]
    w = points @ world_to_clip[3, :3] + world_to_clip[3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        x = (h[:, 0] / w + 1.0) * 0.5 * camera.width
        y = (1.0 - h[:, 1] / w) * 0.5 * camera.height
    return np.stack([x, y, w], axis=1)


def _box_planes(points: np.ndarray, eye: np.ndarray, world_to_clip: np.ndarray) -> np.ndarray:
    """Clip-space planes keeping what lies behind the reflector's bounding-box faces that
    face the eye (at most three of the six)."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    planes = []
    for axis in range(3):
        for sign, bound in ((1.0, hi[axis]), (-1.0, lo[axis])):
            if sign * (eye[axis] - bound) > 0:  # this face looks at the eye
                plane = np.zeros(4)
                plane[axis] = -sign
                plane[3] = sign * bound
                clip = transform_plane(plane, world_to_clip)
                planes.append(clip / np.abs(clip).max())
    return np.array(planes).reshape(-1, 4)
