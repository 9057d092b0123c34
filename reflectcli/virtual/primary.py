"""A virtual frame's primary pass: `render_primary`'s frame, with the threads' buffers
merged, the pixels shaded and the mirrors' pixel boxes found in one parallel region
instead of three kernels (the rasterizer's `_resolve`, `_shade` and `mirror_boxes`): each
row is merged just before it is shaded (still in cache), and its mirror pixels counted
just after. On four-spheres at 2 threads the merge alone was 0.5 ms of an 11 ms frame (a
pass over the image's 1 MB of ids and depths and both threads' buffers), no faster on two
threads than on one. The bytes are those of `render_primary` and `mirror_boxes`."""

from __future__ import annotations

import time

import numba
import numpy as np
from numba import njit, prange

from ..camera import Camera, standard_planes
from ..frame import Frame
from ..parallel import claim, counter
from ..raster.closed import primary_pass_flags
from ..raster.primary import Primary, render_primary
from ..raster.rasterize import RasterBuffers, RasterWorkspace
from ..raster.rasterize.buffers import thread_buffers
from ..raster.rasterize.constants import _CHUNK, CULL_NONE
from ..raster.rasterize.draw import _draw
from ..raster.rasterize.fixed import guarded_planes
from ..raster.rasterize.resolve import resolve_row
from ..raster.shade import _ROWS, _shade_row
from ..scene.types import Scene, Triangles
from .compose import mirror_boxes


def primary_and_boxes(scene: Scene, frame_index: int, camera: Camera, ws: RasterWorkspace,
                      label_of: np.ndarray, labels: np.ndarray,
                      stencil: np.ndarray) -> tuple[Primary, np.ndarray, np.ndarray, bool]:
    """(render_primary(scene, frame_index, camera, workspace=ws), mirror_boxes' (counts,
    boxes) of its surface ids, labelled), the same bytes. The frame's arrays (rgb, depth,
    surface, mirror mask) are its own; the triangle ids are the workspace's (read within
    the frame only: valid until the next call).

    `labelled` True: `labels` (H, W uint8) holds label_of[k] (M,) on mirror k's pixels and
    0 on every other pixel, and `stencil` (H, W bool) labels != 0: `pass_labels`' labels
    and stencil in any box."""
    t0 = time.perf_counter()
    geometry = scene.geometry(frame_index)
    tris = geometry.all_triangles()
    width, height = camera.width, camera.height
    n_objects, n_mirrors = scene.n_objects, scene.mirrors.count
    if tris.count == 0 or width <= 0 or height <= 0:
        primary = render_primary(scene, frame_index, camera, workspace=ws)
        return (primary, *mirror_boxes(primary.frame.surface, n_objects, n_mirrors), False)
    corners, all_planes, n_cut, bits = ws.kept(
        "primary_setup", tris, (width, height), lambda: _setup(tris, width, height))
    # closed surfaces seen from outside: their back faces culled (raster/closed.py)
    flags, draw_flags = primary_pass_flags(geometry, camera, n_objects, ws)
    m = np.ascontiguousarray(camera.clip_from_world(), dtype=np.float64)
    tri = ws.get("primary_tri", (height, width), np.int32)
    depth = np.empty((height, width), np.float32)
    no_mask = ws.constant("stencil", (1, 1), np.uint8, 1)
    floor = ws.constant("floor", (1, 1), np.float32, 0.0)
    threads = max(1, numba.get_num_threads())
    own_tri, own_key = thread_buffers(ws, threads, height, width)
    drew = np.zeros(threads, np.bool_)
    chunks = (corners.shape[0] + _CHUNK - 1) // _CHUNK
    bounds = ws.chunk_bounds(corners)
    _draw(corners, draw_flags, m, all_planes, n_cut, width, height, bits, CULL_NONE,
          chunks, bounds, no_mask, False, floor, False, 0, width, 0, height, own_tri, own_key,
          drew)
    t1 = time.perf_counter()
    rgb = np.empty((height, width, 3), np.float32)
    surface = np.empty((height, width), np.int32)
    mirror_mask = np.empty((height, width), np.bool_)
    counts = np.empty(n_mirrors, np.int64)
    boxes = np.empty((n_mirrors, 4), np.int64)
    mats, lights = scene.materials, scene.lights
    _primary_rows(flags, own_tri, own_key, drew, tri, depth, m, corners, tris.corners, tris.uvs,
                  tris.normals, tris.material, tris.surface, n_objects,
                  np.asarray(camera.eye, np.float64), mats.mat_i, mats.mat_f, mats.texels,
                  lights.light_f, scene.shading, scene.ambient, scene.background,
                  scene.mirrors.reflectance, scene.mirrors.base, rgb, surface, mirror_mask,
                  counts, boxes, label_of, labels, stencil, threads)
    t2 = time.perf_counter()
    frame = Frame(rgb=rgb, depth=depth, surface=surface, mirror_mask=mirror_mask,
                  timings={"rasterize": t1 - t0, "shade": t2 - t1},
                  stats={"triangles": tris.count})
    buffers = RasterBuffers(tri, None, None, depth, corners, m)
    return Primary(frame, buffers, tris, flags, geometry), counts, boxes, True


def _setup(tris: Triangles, width: int,
           height: int) -> tuple[np.ndarray, np.ndarray, int, int]:
    """(corners (float32, contiguous), clip planes, how many of them cut (the rest are the
    guard band), subpixel bits): what `render_primary` and `rasterize` make every frame,
    kept by the caller while the same triangles are drawn at the same size."""
    # `rasterize` with no mask, no depth floor, near and far planes, no culling
    planes = standard_planes()
    all_planes, bits = guarded_planes(planes, width, height)
    corners = np.ascontiguousarray(tris.corners, dtype=np.float32)
    return corners, all_planes, planes.shape[0], bits


@njit(cache=True, parallel=True)
def _primary_rows(flags, own_tri, own_key, drew, tri, depth, m, drawn, corners, uvs, normals,
                  material, surface, n_objects, eye, mat_i, mat_f, texels, light_f, shading,
                  ambient, background, refl, base, rgb, surf, mirror_mask, counts, boxes,
                  label_of, labels, stencil, threads):
    """Rows claimed _ROWS at a time by whichever thread is free: each row's threads'
    buffers merged into `tri` and `depth` (`_resolve`'s row over the whole image), the row
    shaded (`_shade`'s row, barycentrics recovered from the drawn corners `drawn`), its mirror mask
    (surface id >= n_objects) set and its mirror pixels counted into the worker's own
    counts and boxes; those are combined at the end (sums, minima, maxima: `mirror_boxes`'
    numbers whoever counted which row), and the row labelled (labels = label_of[k] on
    mirror k's pixels, 0 elsewhere; stencil = labels != 0). A row's shading reads only its
    own row's ids."""
    h, w = tri.shape
    n_mirrors = counts.shape[0]
    owners = np.flatnonzero(drew)
    no_stencil = np.empty((1, 1), np.bool_)  # never read
    no_stencil[0, 0] = False
    no_dirs = np.empty((1, 1, 3))  # never read: shading sees along eye -> point
    g = np.empty((threads, 12, w))
    xs = np.empty((threads, w), np.int64)
    own_counts = np.empty((threads, n_mirrors), np.int64)
    own_boxes = np.empty((threads, n_mirrors, 4), np.int64)
    for me in range(threads):
        for k in range(n_mirrors):
            own_counts[me, k] = 0
            own_boxes[me, k, 0] = h
            own_boxes[me, k, 1] = 0
            own_boxes[me, k, 2] = w
            own_boxes[me, k, 3] = 0
    claimed = counter()
    pieces = (h + _ROWS - 1) // _ROWS
    for me in prange(threads):
        while True:
            piece = claim(claimed)
            if piece >= pieces:
                break
            for y in range(piece * _ROWS, min(h, (piece + 1) * _ROWS)):
                resolve_row(flags, y, 0, w, 0, h, 0, w, owners, own_tri, own_key, tri, depth)
                _shade_row(y, 0, w, no_stencil, False, g[me], xs[me], tri, m, drawn,
                           corners, uvs, normals, material, surface, n_objects, eye, no_dirs,
                           False, mat_i, mat_f, texels, light_f, shading, ambient, background,
                           refl, base, rgb, surf)
                top = -1
                for x in range(w):
                    s = surf[y, x]
                    top = max(top, s)
                    mirror_mask[y, x] = s >= n_objects
                if top < n_objects:
                    for x in range(w):
                        labels[y, x] = 0
                        stencil[y, x] = False
                    continue
                for x in range(w):
                    k = surf[y, x] - n_objects
                    label = label_of[k] if 0 <= k < n_mirrors else np.uint8(0)
                    labels[y, x] = label
                    stencil[y, x] = label != 0
                    if 0 <= k < n_mirrors:
                        own_counts[me, k] += 1
                        own_boxes[me, k, 0] = min(own_boxes[me, k, 0], y)
                        own_boxes[me, k, 1] = max(own_boxes[me, k, 1], y + 1)
                        own_boxes[me, k, 2] = min(own_boxes[me, k, 2], x)
                        own_boxes[me, k, 3] = max(own_boxes[me, k, 3], x + 1)
    for k in range(n_mirrors):
        counts[k] = 0
        boxes[k, 0] = h
        boxes[k, 1] = 0
        boxes[k, 2] = w
        boxes[k, 3] = 0
        for me in range(threads):
            counts[k] += own_counts[me, k]
            boxes[k, 0] = min(boxes[k, 0], own_boxes[me, k, 0])
            boxes[k, 1] = max(boxes[k, 1], own_boxes[me, k, 1])
            boxes[k, 2] = min(boxes[k, 2], own_boxes[me, k, 2])
            boxes[k, 3] = max(boxes[k, 3], own_boxes[me, k, 3])
        if counts[k] == 0:
            for c in range(4):
                boxes[k, c] = 0
