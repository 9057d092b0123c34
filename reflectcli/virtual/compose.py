"""The per-frame steps around a virtual pass, as kernels over what they touch (numba): which
mirrors the eye sees and their pixels' boxes, a part's virtual triangles gathered for the
rasterizer, and one-pixel cracks closed. Done with numpy they made whole-image masks and
index lists per part, several milliseconds a frame on four small spheres."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..raster.rasterize.gather import gather_triangle


@njit(cache=True)
def mirror_boxes(surface, n_objects, n_mirrors):
    """(counts (M,) int64, boxes (M, 4) int64 rows y0, y1, x0, x1 (exclusive ends)) of each
    mirror's pixels in a surface-id image (H, W) (mirror k is surface n_objects + k); a
    mirror with no pixel has the box (0, 0, 0, 0)."""
    h, w = surface.shape
    counts = np.zeros(n_mirrors, np.int64)
    boxes = np.zeros((n_mirrors, 4), np.int64)
    boxes[:, 0] = h
    boxes[:, 2] = w
    for y in range(h):
        # a row's greatest id first (a loop without branches, vectorised): most rows hold
        # no mirror and need no look at each pixel
        top = -1
        for x in range(w):
            top = max(top, surface[y, x])
        if top < n_objects:
            continue
        for x in range(w):
            k = surface[y, x] - n_objects
            if 0 <= k < n_mirrors:
                counts[k] += 1
                boxes[k, 0] = min(boxes[k, 0], y)
                boxes[k, 1] = max(boxes[k, 1], y + 1)
                boxes[k, 2] = min(boxes[k, 2], x)
                boxes[k, 3] = max(boxes[k, 3], x + 1)
    for k in range(n_mirrors):
        if counts[k] == 0:
            boxes[k, :] = 0
    return counts, boxes


@njit(cache=True, parallel=True)
def part_stencil(triangle, surface, sid, first, in_part, out):
    """out (H, W) bool: the pixels of surface `sid` whose triangle (an index of the soup,
    `triangle`) is reflector face f = triangle - first with in_part[f] (in_part holds the
    reflector's count faces and one more, False, for any other triangle)."""
    h, w = triangle.shape
    count = in_part.shape[0] - 1
    for y in prange(h):
        for x in range(w):
            f = triangle[y, x] - first
            f = f if 0 <= f < count else count
            out[y, x] = surface[y, x] == sid and in_part[f]


@njit(cache=True, parallel=True)
def gather_corners(virtual, hidden, corner_index, surface, n_objects, corners, flags):
    """corners[t, i] = virtual[corner_index[t, i]] in float32 (what the rasterizer takes),
    and the rasterizer's flags[t]: FLAG_MIRROR for a mirror's triangle (surface[t] >=
    n_objects), FLAG_SKIP where all three of its points are hidden (the paper drops polygons
    wholly in the hidden region; mixed ones keep their doubly virtual vertices). The same
    per triangle as `rasterize_passes` gathers them as it draws (`gather_triangle`)."""
    for t in prange(corner_index.shape[0]):
        gather_triangle(virtual, hidden, corner_index, surface, n_objects, corners, flags, t)


@njit(cache=True, inline="always")
def _covered(triangle, stencil, y, x):
    return stencil[y, x] and triangle[y, x] >= 0


@njit(cache=True)
def fill_cracks(colors, triangle, stencil, y0, y1, x0, x1):
    """Close one-pixel cracks between virtual triangles, in place, within rows y0..y1-1 and
    columns x0..x1-1 (the stencil's box): a stencil pixel no fragment covered whose two
    neighbours across it (above and below, or left and right) are covered takes their mean
    color, summed in float64 in that order (above, below, left, right). Covered: a stencil
    pixel with a triangle (`triangle` (H, W) >= 0) - a masked pass draws nowhere else, and
    outside the stencil's box its buffer holds whatever an earlier pass left.

    Curved reflectors only. Reflected triangles are split n x n with n chosen per triangle
    (by its longest edge), so two neighbours split differently meet in a T-junction; the
    finer side's extra virtual vertices bend off the coarser side's straight virtual edge,
    and pixel centers fall through the sliver between them (cylinder: 21 background pixels
    along the reflected wall/floor seam). A reflection one pixel wide between covered pixels
    on both sides is not something the tessellated objects can show, so the fill is safe;
    wider gaps (a reflection of the background) are kept. A crack's neighbours are covered,
    so never cracks themselves: filling in place reads only unchanged pixels.

    One thread: a box's few thousand pixels take microseconds, less than a parallel region
    costs when the machine's other work holds a core (its barrier then waits for it)."""
    h, w = triangle.shape
    for y in range(y0, y1):
        for x in range(x0, x1):
            if not stencil[y, x] or triangle[y, x] >= 0:
                continue
            _fill_crack(colors, y, x,
                        y >= 1 and y + 1 < h and _covered(triangle, stencil, y - 1, x)
                        and _covered(triangle, stencil, y + 1, x),
                        x >= 1 and x + 1 < w and _covered(triangle, stencil, y, x - 1)
                        and _covered(triangle, stencil, y, x + 1))


@njit(cache=True, inline="always")
def _fill_crack(colors, y, x, vertical, horizontal):
    """colors[y, x] = the mean of the pairs of neighbours across it that count (`vertical`:
    above and below; `horizontal`: left and right), summed in float64 in that order; left
    as it is when neither does. Shared by fill_cracks and compose_passes, which differ only
    in what counts as a covered neighbour."""
    t0 = t1 = t2 = 0.0
    count = 0
    if vertical:
        for dy in (-1, 1):
            t0 += np.float64(colors[y + dy, x, 0])
            t1 += np.float64(colors[y + dy, x, 1])
            t2 += np.float64(colors[y + dy, x, 2])
        count += 2
    if horizontal:
        for dx in (-1, 1):
            t0 += np.float64(colors[y, x + dx, 0])
            t1 += np.float64(colors[y, x + dx, 1])
            t2 += np.float64(colors[y, x + dx, 2])
        count += 2
    if count:
        colors[y, x, 0] = np.float32(t0 / count)
        colors[y, x, 1] = np.float32(t1 / count)
        colors[y, x, 2] = np.float32(t2 / count)


@njit(cache=True, parallel=True)
def pass_labels(surface, depth, n_objects, label_of, y0, y1, x0, x1, labels, stencil, floor):
    """Within rows y0..y1-1 and columns x0..x1-1: labels (uint8) = label_of[k] on mirror
    k's pixels (surface n_objects + k; 0 for a mirror not drawn together, and for objects
    and background), `stencil` = labels != 0, and the depth floor `floor` = `depth` on
    the labelled pixels, 0 elsewhere (as `draw_virtual` sets it for each pass alone).
    Rows in parallel: serial, the box's tens of thousands of pixels took 0.35 ms of a
    four-spheres frame, several parallel regions' worth."""
    m = label_of.shape[0]
    for y in prange(y0, y1):
        for x in range(x0, x1):
            k = surface[y, x] - n_objects
            label = label_of[k] if 0 <= k < m else np.uint8(0)
            labels[y, x] = label
            stencil[y, x] = label != 0
            floor[y, x] = depth[y, x] if label != 0 else np.float32(0.0)


@njit(cache=True, inline="always")
def _same(triangle, labels, label, y, x):
    """Pixel (y, x) covered by a triangle of pass `label` (a crack's neighbour)."""
    return labels[y, x] == label and triangle[y, x] >= 0


@njit(cache=True, parallel=True)
def compose_passes(rgb, colors, triangle, labels, reflectance, y0, y1, x0, x1):
    """Several reflectors' passes drawn at once (labels p + 1, reflectance[p]) composed
    within rows y0..y1-1 and columns x0..x1-1: `fill_cracks` on each label's pixels with
    only that label's pixels counted as covered, then `add_reflection` (rgb +=
    reflectance[p] * colors on label p + 1): the bytes of the passes done one at a time.
    A crack's neighbours are covered, never filled, and a row's adding reads only its own
    row's colours: so each row is filled then added on its own, rows in parallel, and the
    order of the pixels does not matter. Nothing outside the box is read."""
    for y in prange(y0, y1):
        _compose_row(rgb, colors, triangle, labels, reflectance, y, y0, y1, x0, x1)


@njit(cache=True, inline="always")
def _compose_row(rgb, colors, triangle, labels, reflectance, y, y0, y1, x0, x1):
    """Row y of `compose_passes`: its cracks filled (reading rows y - 1 and y + 1 where
    they lie in the box), then its reflections added."""
    for x in range(x0, x1):
        label = labels[y, x]
        if label == 0 or triangle[y, x] >= 0:
            continue
        # neighbours inside the box only: outside it labels and triangles are another
        # frame's or pass's (each label's pixels all lie inside the box)
        _fill_crack(colors, y, x,
                    y - 1 >= y0 and y + 1 < y1 and _same(triangle, labels, label, y - 1, x)
                    and _same(triangle, labels, label, y + 1, x),
                    x - 1 >= x0 and x + 1 < x1 and _same(triangle, labels, label, y, x - 1)
                    and _same(triangle, labels, label, y, x + 1))
    for x in range(x0, x1):
        label = labels[y, x]
        if label != 0:
            for c in range(3):
                rgb[y, x, c] += reflectance[label - 1, c] * colors[y, x, c]
