"""A mesh reflector's part passes drawn together: every part's virtual triangles
rasterized in one call over a label image (the part under each pixel), shaded once, cracks
filled and reflections added per label, as the sphere mirrors are drawn together
(together.py). One at a time, the mask's 14 parts made 14 stencils, gathers, rasterizations,
shadings and blends (about 5 parallel regions a part). The bytes are the passes' one at a
time (rasterize_passes, compose_passes)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit, prange

from ..raster.primary import Primary
from ..raster.rasterize import RasterWorkspace
from ..raster.rasterize.passes import MAX_PASSES, rasterize_passes
from ..raster.shade import shade_buffers
from ..scene.types import Scene
from .compose import compose_passes
from .tessellation import Tessellation, concatenate_tessellations


@dataclass
class PartPassCache:
    """The last tessellation joined with itself once per part pass (a still scene draws
    the same one every frame), its corner indices int32 while they fit (as the sphere
    mirrors' joined ones, together.py: the draw's gather then compiles once)."""

    entries: dict = field(default_factory=dict)

    def get(self, tess: Tessellation, count: int) -> Tessellation:
        """`tess` joined `count` times: pass p's triangles t + p T, corner indices into
        pass p's copy of the points."""
        key = (id(tess), count)
        hit = self.entries.get(key)
        if hit is None or hit[0] is not tess:
            self.entries.clear()
            joined = concatenate_tessellations([tess] * count)
            index = np.int32 if len(joined.points) < 2**31 else np.int64
            joined = Tessellation(joined.triangles, joined.points,
                                  np.ascontiguousarray(joined.corner_index, index))
            hit = self.entries[key] = (tess, joined)
        return hit[1]


@njit(cache=True, parallel=True)
def part_labels(triangle, surface, sid, first, label_of, y0, y1, x0, x1, depth, labels,
                stencil, floor, boxes):
    """Within rows y0..y1-1 and columns x0..x1-1 (the reflector's box): labels (uint8) =
    label_of[f] on the pixels of surface `sid` whose triangle is reflector face f =
    triangle - first (label_of (F + 1,): a part's label, or 0; its last entry, 0, for any
    other triangle), 0 elsewhere; `stencil` = labels != 0; the depth floor `floor` =
    `depth` on labelled pixels, 0 elsewhere; boxes[l - 1] (y0, y1, x0, x1) the box of label
    l's pixels, as stencil_box finds it ((0, 0, 0, 0) for a label with none). The rows in
    _LABEL_BANDS bands, each with boxes of its own, then joined (least and greatest rows
    and columns: the same boxes whichever band a pixel is in)."""
    count = label_of.shape[0] - 1
    h, w = triangle.shape
    bands = _LABEL_BANDS
    band_boxes = np.empty((bands, boxes.shape[0], 4), np.int64)
    for band in prange(bands):
        own = band_boxes[band]
        own[:, 0] = h
        own[:, 1] = 0
        own[:, 2] = w
        own[:, 3] = 0
        for y in range(y0 + (y1 - y0) * band // bands, y0 + (y1 - y0) * (band + 1) // bands):
            for x in range(x0, x1):
                f = triangle[y, x] - first
                f = f if 0 <= f < count else count
                label = label_of[f] if surface[y, x] == sid else np.uint8(0)
                labels[y, x] = label
                stencil[y, x] = label != 0
                floor[y, x] = depth[y, x] if label != 0 else np.float32(0.0)
                if label != 0:
                    b = label - 1
                    own[b, 0] = min(own[b, 0], y)
                    own[b, 1] = y + 1
                    own[b, 2] = min(own[b, 2], x)
                    own[b, 3] = max(own[b, 3], x + 1)
    for b in range(boxes.shape[0]):
        boxes[b, 0], boxes[b, 1], boxes[b, 2], boxes[b, 3] = h, 0, w, 0
        for band in range(bands):
            boxes[b, 0] = min(boxes[b, 0], band_boxes[band, b, 0])
            boxes[b, 1] = max(boxes[b, 1], band_boxes[band, b, 1])
            boxes[b, 2] = min(boxes[b, 2], band_boxes[band, b, 2])
            boxes[b, 3] = max(boxes[b, 3], band_boxes[band, b, 3])
        if boxes[b, 1] == 0:
            boxes[b, :] = 0


_LABEL_BANDS = 16  # row bands of part_labels (a fixed count: no answer depends on threads)


def label_parts(primary: Primary, sid: int, first: int, label_of: np.ndarray,
                box: tuple[int, int, int, int], ws: RasterWorkspace):
    """part_labels over mirror `sid`'s box (its faces from soup triangle `first` on, a
    label per face in label_of): (labels, stencil, floor, boxes (L, 4)), workspace
    arrays (valid until the next call), L = label_of.max()."""
    h, w = primary.frame.surface.shape
    labels = ws.get("part_labels", (h, w), np.uint8)
    stencil = ws.get("part_stencil", (h, w), np.bool_)
    floor = ws.get("virtual_floor", (h, w), np.float32)
    boxes = np.empty((int(label_of.max()), 4), np.int64)
    part_labels(primary.buffers.triangle, primary.frame.surface, sid, first, label_of, *box,
                primary.buffers.depth, labels, stencil, floor, boxes)
    return labels, stencil, floor, boxes


def draw_parts(scene: Scene, primary: Primary, eye: np.ndarray, clip_from_world: np.ndarray,
               k: int, tess: Tessellation, joined: Tessellation, labelled: tuple,
               virtual: np.ndarray, hidden: np.ndarray, box: tuple[int, int, int, int],
               zbuffer: bool, incoming: np.ndarray | None, ws: RasterWorkspace) -> None:
    """The reflection in mirror k's parts (P of them, each with pixels: `labelled`,
    label_parts' answer with labels 1..P; virtual (P, N, 3) float32 (the rounding the
    draw's gather makes) and hidden (P, N), each part's answers for the points of `tess`;
    `joined`: PartPassCache's) added to the primary frame's rgb, as draw_virtual and
    add_reflection give them part by part: one rasterization of all passes over the label
    image, gathering the corners as it goes (the depth floor where `zbuffer`), one shading
    merging the threads' buffers as it goes, cracks filled and reflections added per
    label. `box`: mirror k's pixels' (the union of the parts' boxes)."""
    count = virtual.shape[0]
    assert count <= MAX_PASSES and virtual.dtype == np.float32
    labels, stencil, floor, boxes = labelled
    frame = primary.frame
    h, w = frame.surface.shape
    n_tris = joined.triangles.count
    corners = ws.get("virtual_corners", (n_tris, 3, 3), np.float32)
    flags = ws.get("virtual_flags", (n_tris,), np.uint8)
    starts = np.arange(count + 1, dtype=np.int64) * tess.triangles.count
    buffers, pending = rasterize_passes(
        corners, flags, clip_from_world, w, h, starts, boxes, labels,
        floor if zbuffer else None, ws,
        gather=(virtual.reshape(-1, 3), hidden.reshape(-1), joined.corner_index,
                joined.triangles.surface, scene.n_objects),
        resolve=False)
    colors, _ = shade_buffers(buffers, joined.triangles, scene, eye, incoming,
                              stencil=stencil,
                              out=(ws.get("virtual_rgb", (h, w, 3), np.float32),
                                   ws.get("virtual_surface", (h, w), np.int32)),
                              box=box, pending=pending)
    # the mirror's reflectance for every label, of its own dtype (add_reflection's sums)
    reflectance = np.ascontiguousarray(np.broadcast_to(scene.mirrors.reflectance[k],
                                                       (count, 3)))
    compose_passes(frame.rgb, colors, buffers.triangle, labels, reflectance, *box)
