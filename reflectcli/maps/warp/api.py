"""warp_maps / warp_depths: the warp of several maps into a mirror's pixels, choosing the
splat (one-pixel and its spread, or zexel squares) and the region it writes."""

from __future__ import annotations

import numpy as np

from ...camera import Camera
from ...camera import screen_from_ndc as _screen_from_ndc
from .buffers import WarpBuffers, stencil_box
from .order import ordered_runs
from .payload import gather_colors
from .pixels import splat_pixels
from .projection import project_map, warp_matrix
from .spreading import spread
from .squares import splat, splat_radii


def warp_maps(maps, camera: Camera, reflection: np.ndarray, mirrored_eye: np.ndarray,
              stencil: np.ndarray, splat_mode, ordered: bool,
              buffers: WarpBuffers | None = None, box=None, payloads=None, out=None):
    """Warp several zexel maps (ZexelMap) into the pixels of `stencil` seen from `camera`.

    Returns (depth (H, W) float32, id (H, W) int64: map index * stride + zexel index, or -1
    where no zexel landed, stride, zexels that landed in the stencil's box grown by the
    splat's reach, on the screen). With `buffers` the results are views of its arrays, valid
    until its next use. `box`, `payloads`, `out`: as for warp_depths."""
    items = []
    for zmap in maps:
        wm = warp_matrix(zmap.camera, camera, reflection)
        runs = None
        if ordered:
            c = zmap.camera
            e = c.clip_from_world() @ np.append(mirrored_eye, 1.0)
            with np.errstate(divide="ignore", invalid="ignore"):
                ex, ey = _screen_from_ndc(e[0] / e[3], e[1] / e[3], c.width, c.height)
            runs = ordered_runs(*zmap.depth.shape, ex, ey, e[3] > 0)
        items.append((zmap.depth, wm, runs))
    return warp_depths(items, camera.near, stencil, splat_mode, ordered, buffers, box, payloads,
                       out)


def warp_depths(items, near: float, stencil: np.ndarray, splat_mode, ordered: bool,
                buffers: WarpBuffers | None = None, box=None, payloads=None, out=None):
    """warp_maps on (depth (mh, mw) float32, W (4, 4) map pixel -> clip, runs or None for
    row-major order) per map: the kernels without the cameras. `box`: the stencil's box
    (x0, x1, y0, y1) if the caller has it. Ids are slot * stride + zexel index, stride the
    power of two at or above the largest map's zexel count.

    Fixed splats in z-buffer mode (and one-pixel ones in ordered mode): each map is splatted
    one pixel a zexel (`splat_pixels`), then a wider splat is the `spread` of that result.
    Adaptive splats and ordered wider ones go zexel by zexel over their squares (`splat`).

    `payloads`: per map an (n, c) array, a row per zexel (colours, triangle ids...); each
    pixel of the box a zexel reached gets its zexel's row in `out` (H, W, c, C-contiguous),
    written by the splat itself (no gather pass); other pixels of `out` (unreached, or off
    the stencil) hold anything."""
    h, w = stencil.shape
    if buffers is None:
        buffers = WarpBuffers(h, w)
    stride = 1 << (max(depth.size for depth, _, _ in items) - 1).bit_length()
    if len(items) * stride > 1 << 32:
        raise ValueError(f"{len(items)} maps of {stride} zexels: warp ids must stay below 2^32")
    if box is None:
        _, box = stencil_box(stencil)
    if box is None:
        buffers.claim(None)
        return buffers.best_zd[:, :, 0], buffers.best_id, stride, 0
    x0, x1, y0, y1 = box
    radius = None if splat_mode == "adaptive" else (int(splat_mode) - 1) // 2
    zexels = 0
    if radius is not None and (radius == 0 or not ordered):
        stencil = np.ascontiguousarray(stencil)
        use_stencil = radius == 0  # (the kernel skips the test where the stencil is all set)
        region = (max(x0 - radius, 0), min(x1 + radius, w), max(y0 - radius, 0),
                  min(y1 + radius, h))
        buffers.claim(region, region)
        for slot, (depth, wm, runs) in enumerate(items):
            mh, mw = depth.shape
            proj = buffers.projection(mh, mw)
            if runs is None:
                runs = buffers.raster_runs(mh, mw)
            # projected inside the splat: zexels beyond the region cannot reach the box
            zexels += splat_pixels(
                proj, runs, mw, slot * stride, stencil, buffers.best_zd, buffers.best_id,
                ordered, region, slot == 0, use_stencil,
                # a spread copies every pixel's row itself
                payload=None if payloads is None or radius > 0 else payloads[slot],
                payload_out=out,
                source=(depth, wm, near, (x0 - radius, x1 + radius, y0 - radius, y1 + radius)))
        if radius == 0:
            return buffers.best_zd[:, :, 0], buffers.best_id, stride, zexels
        buffers.claim_out(box)
        spread(buffers.best_zd, buffers.best_id, radius, stencil, box, buffers.out_z,
               buffers.out_id, payloads, stride, out)
        return buffers.out_z, buffers.out_id, stride, zexels
    buffers.claim(box)
    best_zd, best_id = buffers.best_zd, buffers.best_id
    ys = np.arange(y0, y1)
    # zexels landing this far outside the stencil's box cannot splat into it
    margin = 8 if splat_mode == "adaptive" else 3
    for slot, (depth, wm, runs) in enumerate(items):
        mh, mw = depth.shape
        proj = buffers.projection(mh, mw)
        sx, sy, z, row_lo, row_hi = project_map(depth, wm, w, h, near, box, margin, proj)
        radii = buffers.fixed_radii(depth.size, splat_mode)
        if splat_mode == "adaptive":
            splat_radii(sx, sy, z, depth.shape, splat_mode, radii)
        if runs is None:
            runs = buffers.raster_runs(mh, mw)
        splat(sx, sy, z, radii, runs, mw, row_lo, row_hi, slot, stride, stencil, best_zd,
              best_id, ordered, rows=ys)
        zexels += int(proj.count.sum())
    if payloads is not None:
        gather_colors(best_id, stride, payloads, box, out)
    return best_zd[:, :, 0], best_id, stride, zexels
