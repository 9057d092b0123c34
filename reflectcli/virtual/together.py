"""The sphere mirrors of a frame drawn together: their virtual vertices found in one call,
their triangles gathered, rasterized, shaded and composed once for all of them, each only
on its own pixels (a label image). Drawn one at a time, four-spheres' frame held 20 parallel
regions for its four spheres with Python between them (now 3: the search, the draw, the
merge with the shading); on two cores each region's start and join cost about as much as
its work. The bytes are those of the passes one at a time."""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np
from numba import njit, prange

from ..parallel import claim, counter
from ..raster.primary import Primary
from ..raster.rasterize import RasterWorkspace
from ..raster.rasterize.passes import MAX_PASSES, rasterize_passes
from ..raster.rasterize.resolve import resolve_row
from ..raster.shade import _shade_row
from ..scene.types import Scene
from .circle import block_scratch, spheres_virtual_vertices
from .compose import _compose_row, pass_labels
from .tessellation import Tessellation, concatenate_tessellations

# drawn together only while the passes' common box is at most this many times the area of
# their own boxes (each thread clears, and the merge visits, the common box)
MAX_SPREAD = 2.0


@dataclass
class Together:
    """Reflectors ks' tessellations joined: points and triangles of reflector ks[p] at
    point_starts[p] .. and tri_starts[p] .., corner indices into the joined points (int32
    while they fit: half the bytes the draw's gather reads, 1 MB less on four-spheres)."""

    ks: tuple[int, ...]
    parts: tuple[Tessellation, ...]  # what it was joined from (identity: still current?)
    joined: Tessellation
    point_starts: np.ndarray  # (P + 1,) int64
    tri_starts: np.ndarray  # (P + 1,) int64
    _arrays: tuple | None = None

    def arrays(self, scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(centers (P, 3), radii (P,), label_of (M,) uint8 with label p + 1 on mirror
        ks[p], reflectance (P, 3)) of the group's spheres: a scene's mirrors do not change,
        so they are made once, not every frame."""
        if self._arrays is None:
            mirrors = scene.mirrors
            ks = list(self.ks)
            centers = np.empty((len(ks), 3))
            radii = np.empty(len(ks))
            for p, k in enumerate(ks):
                centers[p], radii[p] = mirrors.sphere(k)
            label_of = np.zeros(mirrors.count, np.uint8)
            label_of[ks] = np.arange(1, len(ks) + 1)
            self._arrays = (centers, radii, label_of,
                            np.ascontiguousarray(mirrors.reflectance[ks]))
        return self._arrays


@dataclass
class TogetherCache:
    """The last joined group (a still scene asks for the same one every frame)."""

    last: Together | None = None
    scratch: dict = field(default_factory=dict)

    def get(self, ks: tuple[int, ...], parts: tuple[Tessellation, ...]) -> Together:
        last = self.last
        if (last is None or last.ks != ks or len(last.parts) != len(parts)
                or any(a is not b for a, b in zip(last.parts, parts, strict=True))):
            point_starts = np.cumsum([0] + [len(t.points) for t in parts]).astype(np.int64)
            tri_starts = np.cumsum([0] + [t.triangles.count for t in parts]).astype(np.int64)
            joined = concatenate_tessellations(list(parts))
            index = np.int32 if len(joined.points) < 2**31 else np.int64
            joined = Tessellation(joined.triangles, np.ascontiguousarray(joined.points,
                                                                         np.float64),
                                  np.ascontiguousarray(joined.corner_index, index))
            self.last = Together(ks, parts, joined, point_starts, tri_starts)
        return self.last

    def block_scratch(self) -> np.ndarray:
        """circle._blocks' per-thread scratch, kept per thread count."""
        threads = max(1, numba.get_num_threads())
        s = self.scratch.get(threads)
        if s is None:
            s = self.scratch[threads] = block_scratch()
        return s


def worth_together(boxes: np.ndarray) -> bool:
    """Whether passes with boxes (P, 4: y0, y1, x0, x1) share a box small enough (see
    MAX_SPREAD) to be drawn together. (Python ints: numpy's reductions on a few numbers
    cost more than the arithmetic, every frame.)"""
    rows = boxes.tolist()
    if len(rows) > MAX_PASSES:
        return False
    area = sum((y1 - y0) * (x1 - x0) for y0, y1, x0, x1 in rows)
    common = ((max(r[1] for r in rows) - min(r[0] for r in rows))
              * (max(r[3] for r in rows) - min(r[2] for r in rows)))
    return common <= MAX_SPREAD * area


def spheres_vertices(scene: Scene, eye: np.ndarray, group: Together, cache: TogetherCache,
                     ws: RasterWorkspace) -> tuple[np.ndarray, np.ndarray]:
    """(virtual (N, 3) world, hidden (N,)) of the joined points of sphere mirrors
    group.ks, each point in its own sphere, in one call (workspace arrays: valid until the
    next call). The virtual points are stored in float32, as the draw's gather reads them
    (the same rounding of the same float64 numbers, half the bytes)."""
    joined = group.joined
    centers, radii = group.arrays(scene)[:2]
    n_points = joined.points.shape[0]
    virtual = ws.get("together_virtual", (n_points, 3), np.float32)
    hidden = ws.get("together_hidden", (n_points,), np.bool_)
    spheres_virtual_vertices(joined.points, eye, centers, radii, group.point_starts, virtual,
                             hidden, cache.block_scratch())
    return virtual, hidden


def sphere_labels(scene: Scene, choose) -> np.ndarray:
    """(M,) uint8: label p + 1 for the p-th of the scene's mirrors `choose(k)` says are
    drawn together (sphere mirrors, in order), 0 for the others: the labels of a frame
    that sees all of them (`draw_spheres`)."""
    label_of = np.zeros(scene.mirrors.count, np.uint8)
    ks = [k for k in range(scene.mirrors.count) if choose(k)][:MAX_PASSES]
    label_of[ks] = np.arange(1, len(ks) + 1)
    return label_of


def labels_buffers(ws: RasterWorkspace, h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """The workspace's label image and stencil (H, W) of the passes drawn together."""
    return ws.get("together_labels", (h, w), np.uint8), ws.get("together_stencil", (h, w),
                                                                np.bool_)


def draw_spheres(scene: Scene, primary: Primary, eye: np.ndarray, clip_from_world: np.ndarray,
                 group: Together, virtual: np.ndarray, hidden: np.ndarray, boxes: np.ndarray,
                 zbuffer: bool, incoming: np.ndarray | None, ws: RasterWorkspace,
                 labelled: np.ndarray | None = None) -> None:
    """The reflections of sphere mirrors group.ks (each seen, boxes (P, 4) of their
    pixels; their virtual points from `spheres_vertices`) added to the primary frame's rgb,
    as `draw_virtual` and `add_reflection` give them one at a time: one rasterization of
    all passes over a label image, gathering the corners as it goes (the depth floor where
    `zbuffer`, the reflector test), one shading, merging the threads' buffers as it goes,
    cracks filled and reflections added per label. `labelled` (M,): the labels the
    workspace's label image already holds (`primary_and_boxes`), used when they are this
    group's (label p + 1 on mirror group.ks[p]); the depth floor is the primary depth
    itself (read only on labelled pixels, where `pass_labels` copies it)."""
    joined = group.joined
    mirrors = scene.mirrors
    n_tris = joined.triangles.count
    corners = ws.get("virtual_corners", (n_tris, 3, 3), np.float32)
    flags = ws.get("virtual_flags", (n_tris,), np.uint8)
    frame = primary.frame
    h, w = frame.surface.shape
    rows = boxes.tolist()
    y0, y1 = min(r[0] for r in rows), max(r[1] for r in rows)
    x0, x1 = min(r[2] for r in rows), max(r[3] for r in rows)
    label_of, reflectance = group.arrays(scene)[2:]
    labels, stencil = labels_buffers(ws, h, w)
    if labelled is None or not np.array_equal(labelled, label_of):
        pass_labels(frame.surface, primary.buffers.depth, scene.n_objects, label_of, y0, y1,
                    x0, x1, labels, stencil, ws.get("virtual_floor", (h, w), np.float32))
    # a pass's fragments are tested against the floor only where its label is
    floor = primary.buffers.depth
    # the threads' buffers merged row by row as the rows are shaded (one region less)
    buffers, pending = rasterize_passes(corners, flags, clip_from_world, w, h, group.tri_starts,
                                        boxes, labels, floor if zbuffer else None, ws,
                                        gather=(virtual, hidden, joined.corner_index,
                                                joined.triangles.surface, scene.n_objects),
                                        resolve=False)
    # shade_buffers(stencil, box, pending) and compose_passes in one region
    assert buffers.recover and tuple(pending[1:5]) == (x0, x1, y0, y1)
    tris = joined.triangles
    mats = scene.materials
    dirs = (np.zeros((1, 1, 3)) if incoming is None
            else np.ascontiguousarray(incoming, np.float64))
    _shade_compose(stencil, buffers.triangle, np.ascontiguousarray(clip_from_world, np.float64),
                   buffers.corners, tris.corners, tris.uvs, tris.normals, tris.material,
                   tris.surface, scene.n_objects, np.asarray(eye, np.float64), dirs,
                   incoming is not None, mats.mat_i, mats.mat_f, mats.texels,
                   scene.lights.light_f, scene.shading, scene.ambient, scene.background,
                   mirrors.reflectance, mirrors.base,
                   ws.get("virtual_rgb", (h, w, 3), np.float32),
                   ws.get("virtual_surface", (h, w), np.int32), y0, y1, x0, x1,
                   max(1, numba.get_num_threads()), pending[0], pending[5], pending[6],
                   pending[7], pending[8], frame.rgb, labels, reflectance)


_PIECE = 12  # rows a worker claims at a time in _shade_compose


@njit(cache=True, parallel=True)
def _shade_compose(stencil, tri, m, drawn, corners, uvs, normals, material, surface,
                   n_objects, eye, dirs, per_pixel, mat_i, mat_f, texels, light_f, shading,
                   ambient, background, refl, base, colors, surf, y0, y1, x0, x1, threads,
                   flags, own_tri, own_key, drew, depth, rgb, labels, reflectance):
    """The passes' rows y0..y1-1 (columns x0..x1-1, the passes' common box) claimed
    _PIECE at a time: each row merged (`_resolve`'s row) and shaded on the stencil into
    `colors` and `surf` (`_shade_stencil_resolving`'s row), and once the row below it is
    shaded, the row before it composed into `rgb` (`compose_passes`' row: cracks filled
    from the rows above and below, reflectances added). A piece's first and last rows
    need a row of another piece: they are composed after the region, one thread. The
    bytes of shade_buffers(pending=...) then compose_passes: a row's shading reads only its
    own row's ids, its composition only finished rows (and a crack's neighbours, covered,
    are never filled)."""
    w = tri.shape[1]
    owners = np.flatnonzero(drew)
    g = np.empty((threads, 12, w))
    xs = np.empty((threads, w), np.int64)
    claimed = counter()
    pieces = (max(y1 - y0, 0) + _PIECE - 1) // _PIECE
    for me in prange(threads):
        while True:
            k = claim(claimed)
            if k >= pieces:
                break
            first = y0 + k * _PIECE
            for y in range(first, min(y1, first + _PIECE)):
                resolve_row(flags, y, x0, x1, y0, y1, x0, x1, owners, own_tri, own_key, tri,
                            depth)
                _shade_row(y, x0, x1, stencil, True, g[me], xs[me], tri, m, drawn, corners,
                           uvs, normals, material, surface, n_objects, eye, dirs, per_pixel,
                           mat_i, mat_f, texels, light_f, shading, ambient, background, refl,
                           base, colors, surf)
                if y - 1 > first:
                    _compose_row(rgb, colors, tri, labels, reflectance, y - 1, y0, y1, x0, x1)
    for k in range(pieces):
        first = y0 + k * _PIECE
        last = min(y1, first + _PIECE) - 1
        _compose_row(rgb, colors, tri, labels, reflectance, first, y0, y1, x0, x1)
        if last > first:
            _compose_row(rgb, colors, tri, labels, reflectance, last, y0, y1, x0, x1)

