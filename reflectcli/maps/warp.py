"""Forward warping of zexel maps into a mirror's pixels (numba), McMillan's 3D warp.

Each zexel at map pixel (u, v) with eye-space depth z has generalized disparity
delta = 1 / z (0 for empty zexels: points at infinity, which still warp correctly as
directions). Its homogeneous map-eye point is D (u, v, 1, delta) with D the map camera's
pixel-to-ray matrix; the world point is V_map^-1 of that, its mirror image R of that, and
its place on the screen P V of that. One 4x4 W = P V R V_map^-1 D per map and frame:
clip = W (u, v, 1, delta), which is equation 3 of the paper written projectively:
x_o ~ delta P_o^-1 (c_i - c_o) + P_o^-1 P_i x_i. The paper's equation 4 disparity,
1 - z_window (far - near) / far, equals near / z for a plain perspective depth buffer: ours up
to the constant `near`, which the projective form absorbs; storing eye-space depth keeps it
exact for the oblique capture projection, whose window z is not that of a plain one.

Visibility: `zbuffer` keeps, per pixel, a zexel of the surface nearest the eye, and of that
surface's zexels (eye depth within SAME_SURFACE) the one that lands nearest the pixel's
center (ties to the lower id); where a surface's zexels in one pixel span more than
SAME_SURFACE in depth (grazing views), which of them is kept can depend on their order.
Keeping simply the nearest depth would pick, on a slanted surface, the zexel on the near
edge of the pixel, a bias that grows as maps get denser; the center rule makes a denser
map converge on the point sample at the center.
`ordered` paints each map in McMillan's occlusion-compatible order (later overwrite),
z-testing only against other maps. Both run one band of screen rows per task over zexels
skipping map rows that cannot reach it, so results do not depend on the thread count.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numba import njit, prange

from ..camera import Camera
from ..camera import screen_from_ndc as _screen_from_ndc
from ..raster.rasterize import screen_from_ndc


def pixel_to_eye(camera: Camera) -> np.ndarray:
    """D: map pixel (u, v, 1, delta) -> homogeneous eye-space point (x/z, y/z, -1, 1/z)."""
    t = math.tan(math.radians(camera.fov_y) / 2.0)
    a = camera.aspect
    w, h = camera.width, camera.height
    return np.array([
        [2.0 * t * a / w, 0.0, (1.0 / w - 1.0) * t * a, 0.0],
        [0.0, -2.0 * t / h, (1.0 - 1.0 / h) * t, 0.0],
        [0.0, 0.0, -1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ])


def warp_matrix(map_camera: Camera, camera: Camera, reflection: np.ndarray) -> np.ndarray:
    """W = P V R V_map^-1 D (see the module docstring)."""
    return (camera.clip_from_world() @ reflection
            @ np.linalg.inv(map_camera.view_matrix()) @ pixel_to_eye(map_camera))


@dataclass
class Projection:
    """One map's projected zexels (reused from frame to frame for maps of one size)."""

    sx: np.ndarray  # (n,) float32 screen x, NaN: not warped
    sy: np.ndarray  # (n,) float32 screen y
    z: np.ndarray  # (n,) float32 eye depth in the target camera
    row_lo: np.ndarray  # (mh,) int64 first screen row a map row reaches
    row_hi: np.ndarray  # (mh,) int64 last screen row a map row reaches
    count: np.ndarray  # (mh,) int64 zexels of the map row that were warped

    @classmethod
    def empty(cls, mh: int, mw: int) -> Projection:
        n = mh * mw
        return cls(np.empty(n, np.float32), np.empty(n, np.float32), np.empty(n, np.float32),
                   np.empty(mh, np.int64), np.empty(mh, np.int64), np.empty(mh, np.int64))


def project_map(depth: np.ndarray, w: np.ndarray, width: int, height: int, near: float,
                box: tuple[int, int, int, int] | None = None, margin: int = 3,
                out: Projection | None = None):
    """Screen positions (float32, pixels) and eye depths of every zexel, and per map row the
    first and last screen row its zexels reach (row_lo > row_hi if none). Zexels behind the
    eye or outside `box` = (x0, x1, y0, y1) grown by `margin` pixels get sx = NaN.
    `out`: arrays to write into (kept across frames), returned filled."""
    if out is None:
        out = Projection.empty(*depth.shape)
    x0, x1, y0, y1 = box if box is not None else (0, width, 0, height)
    _project(depth, np.ascontiguousarray(w, np.float64), near, float(x0 - margin),
             float(x1 + margin), float(y0 - margin), float(y1 + margin), width, height,
             out.sx, out.sy, out.z, out.row_lo, out.row_hi, out.count)
    return out.sx, out.sy, out.z, out.row_lo, out.row_hi


@njit(cache=True, parallel=True)
def _project(depth, w, near, xmin, xmax, ymin, ymax, width, height, sx, sy, z, row_lo, row_hi,
             count):
    mh, mw = depth.shape
    for v in prange(mh):
        # per-row terms hoisted: clip = W[:, 0] u + (W[:, 1] v + W[:, 2]) + W[:, 3] delta
        r0 = w[0, 1] * v + w[0, 2]
        r1 = w[1, 1] * v + w[1, 2]
        r3 = w[3, 1] * v + w[3, 2]
        lo = 1 << 40
        hi = -1
        warped = 0
        for u in range(mw):
            k = v * mw + u
            d = depth[v, u]
            a0 = w[0, 0] * u + r0
            a1 = w[1, 0] * u + r1
            a3 = w[3, 0] * u + r3
            if d == np.inf:  # delta = 0: a direction
                cx = a0
                cy = a1
                cw = a3
                zz = np.inf
                ok = cw > 0.0
            elif d > 0.0:
                # d * clip: the same point (d > 0), without dividing by d; its w is then the
                # eye depth in the target camera
                cx = a0 * d + w[0, 3]
                cy = a1 * d + w[1, 3]
                cw = a3 * d + w[3, 3]
                zz = cw
                ok = zz > near
            else:  # NaN or a non-positive depth: not a zexel
                ok = False
                cx = cy = cw = zz = 0.0
            if not ok:
                sx[k] = np.nan
                continue
            inv = 1.0 / cw
            x, y = screen_from_ndc(cx * inv, cy * inv, width, height)
            if not (xmin <= x < xmax and ymin <= y < ymax):
                sx[k] = np.nan
                continue
            sx[k] = x
            sy[k] = y
            z[k] = zz
            py = int(math.floor(sy[k]))  # the float32 row the splat will use
            lo = min(lo, py)
            hi = max(hi, py)
            warped += 1
        row_lo[v] = lo
        row_hi[v] = hi
        count[v] = warped


def splat_radii(sx, sy, z, shape, mode, out: np.ndarray | None = None) -> np.ndarray:
    """Per-zexel splat radius: fixed (1 -> 0, 3 -> 1, 5 -> 2) or adaptive from the warp's
    local footprint (half the screen distance to the right and lower neighbours, within a
    surface: neighbours more than 5% apart in depth do not count), capped at 3.
    `out`: an int8 array to write adaptive radii into."""
    if mode != "adaptive":
        return np.full(sx.shape[0], (int(mode) - 1) // 2, np.int8)
    radii = np.empty(sx.shape[0], np.int8) if out is None else out
    _adaptive(sx, sy, z, shape[0], shape[1], radii)
    return radii


@njit(cache=True, parallel=True)
def _adaptive(sx, sy, z, mh, mw, radii):
    for v in prange(mh):
        for u in range(mw):
            k = v * mw + u
            radii[k] = 0
            if np.isnan(sx[k]):
                continue
            reach = 0.0
            for du, dv in ((1, 0), (0, 1), (-1, 0), (0, -1)):
                uu, vv = u + du, v + dv
                if uu < 0 or vv < 0 or uu >= mw or vv >= mh:
                    continue
                q = vv * mw + uu
                if np.isnan(sx[q]):
                    continue
                if not (abs(z[q] - z[k]) <= 0.05 * min(z[q], z[k])):
                    continue
                reach = max(reach, abs(sx[q] - sx[k]), abs(sy[q] - sy[k]))
            radii[k] = min(3, int(math.ceil(reach * 0.5 - 0.5))) if reach > 1.0 else 0


def ordered_runs(mh: int, mw: int, epipole_x: float, epipole_y: float, toward: bool):
    """McMillan's occlusion-compatible order over a map as runs (row, first col, stop, step):
    split at the epipole's row and column into up to four sheets; in each, rows and columns
    run from the borders toward the epipole (`toward`: the desired center of projection is in
    front of the map camera) or away from it."""
    # an epipole at infinity (desired COP on the map camera's plane) lies beyond a border
    ex = int(math.floor(np.clip(np.nan_to_num(epipole_x, nan=mw / 2), -1, mw)))
    ey = int(math.floor(np.clip(np.nan_to_num(epipole_y, nan=mh / 2), -1, mh)))
    rows_top = list(range(0, max(ey + 1, 0)))  # rows at or above the epipole row
    rows_bottom = list(range(mh - 1, max(ey, -1), -1))  # rows below it, bottom up
    left = (0, max(ex + 1, 0), 1)  # columns at or left of the epipole, left to right
    right = (mw - 1, max(ex, -1), -1)  # columns right of it, right to left
    if not toward:
        rows_top, rows_bottom = rows_top[::-1], rows_bottom[::-1]
        left = (left[1] - 1, left[0] - 1, -1)
        right = (right[1] + 1, right[0] + 1, 1)
    runs = []
    for rows in (rows_top, rows_bottom):
        for c0, c1, step in (left, right):
            if (c1 - c0) * step > 0:
                runs += [(v, c0, c1, step) for v in rows]
    return np.array(runs, np.int64).reshape(-1, 4)


def raster_runs(mh: int, mw: int) -> np.ndarray:
    """Plain row-major order (zexel index order) as runs."""
    runs = np.zeros((mh, 4), np.int64)
    runs[:, 0] = np.arange(mh)
    runs[:, 2] = mw
    runs[:, 3] = 1
    return runs


SAME_SURFACE = 0.01  # relative eye-depth difference within which two zexels are one surface


def splat(sx, sy, z, radii, runs, mw, row_lo, row_hi, slot, stride, stencil, best_zd, best_id,
          ordered: bool, bands: int | None = None, rows: np.ndarray | None = None) -> None:
    """Write the zexels, visited run by run, into the per-pixel buffers over `stencil`:
    best_zd (H, W, 2) float32 (front depth, squared distance of the kept zexel to the pixel
    center) and best_id; ids are slot * stride + zexel index. `row_lo`/`row_hi`: per map row, the
    screen rows its zexels land on (splats add their radius).

    One band of screen rows per task: each band visits every run but skips the map rows
    that cannot reach it, so the work per band stays close to the zexels that land in it,
    and the result does not depend on the thread count. `bands`: how many (default: two a
    thread). `rows`: the stencil's rows that hold a pixel, if the caller has them."""
    if rows is None:
        rows = np.flatnonzero(stencil.any(axis=1))
    if rows.size == 0:
        return
    reach = int(radii.max()) if radii.size else 0
    if bands is None:
        bands = max(1, numba.get_num_threads()) * 2
    edges = np.linspace(rows[0], rows[-1] + 1, bands + 1).round().astype(np.int64)
    _splat(sx, sy, z, radii, runs, mw, row_lo - reach, row_hi + reach, slot, stride, stencil,
           best_zd, best_id, edges, ordered)


@njit(cache=True, parallel=True)
def _splat(sx, sy, z, radii, runs, mw, row_lo, row_hi, slot, stride, stencil, best_zd, best_id,
           edges, ordered):
    width = stencil.shape[1]
    for b in prange(edges.shape[0] - 1):
        row0 = edges[b]
        row1 = edges[b + 1]
        for run in range(runs.shape[0]):
            v = runs[run, 0]
            if row_hi[v] < row0 or row_lo[v] >= row1:
                continue
            for u in range(runs[run, 1], runs[run, 2], runs[run, 3]):
                k = v * mw + u
                if np.isnan(sx[k]):
                    continue
                py = int(math.floor(sy[k]))
                r = radii[k]
                if py + r < row0 or py - r >= row1:
                    continue
                fx = sx[k]
                fy = sy[k]
                px = int(math.floor(fx))
                zk = z[k]
                ident = slot * stride + k
                if r == 0:  # one pixel: the common case, without the loops
                    if 0 <= px < width and stencil[py, px]:
                        dk = (fx - px - 0.5) ** 2 + (fy - py - 0.5) ** 2
                        _write(py, px, zk, dk, ident, slot, stride, best_zd, best_id,
                               ordered)
                    continue
                for y in range(max(py - r, row0), min(py + r, row1 - 1) + 1):
                    for x in range(max(px - r, 0), min(px + r, width - 1) + 1):
                        if stencil[y, x]:
                            dk = (fx - x - 0.5) ** 2 + (fy - y - 0.5) ** 2
                            _write(y, x, zk, dk, ident, slot, stride, best_zd, best_id,
                                   ordered)


@njit(cache=True, inline="always")
def _write(y, x, zk, dk, ident, slot, stride, best_zd, best_id, ordered):
    """The visibility rule at one pixel, against the zexel kept so far (its eye depth in
    best_zd[..., 0], its squared distance to the pixel center in best_zd[..., 1]: one cache
    line). z-buffer: a zexel more than SAME_SURFACE nearer takes the pixel; one within
    SAME_SURFACE of it (the same surface) takes it if it lands nearer the center (ties to the
    lower id). So the kept zexel is never more than SAME_SURFACE behind any that arrived.
    Ordered mode: a zexel of the same map wins regardless (McMillan's order)."""
    current = best_id[y, x]
    bz = best_zd[y, x, 0]
    if current < 0 or zk < bz * (1.0 - SAME_SURFACE) or (
            ordered and current // stride == slot):
        best_zd[y, x, 0] = zk
        best_zd[y, x, 1] = dk
        best_id[y, x] = ident
    elif zk <= bz * (1.0 + SAME_SURFACE) or zk == bz:  # == for two zexels at infinity
        # selects, not branches: which zexel lands nearer the center is close to random
        bd = best_zd[y, x, 1]
        take = (dk < bd) | ((dk == bd) & (ident < current))
        best_zd[y, x, 0] = zk if take else bz
        best_zd[y, x, 1] = dk if take else bd
        best_id[y, x] = ident if take else current


class WarpBuffers:
    """The warp's per-frame arrays, kept across frames: page faults on fresh arrays cost more
    than the warp itself. Everything the warp writes lies in `dirty` = (y0, y1, x0, x1), the
    box of the last stencil, which the next use resets (outside it the buffers stay clear)."""

    def __init__(self, height: int, width: int) -> None:
        self.shape = (height, width)
        self.best_zd = np.full((height, width, 2), np.inf, np.float32)
        self.best_id = np.full((height, width), -1, np.int64)
        self.projections: dict[tuple[int, int], Projection] = {}
        self.radii: dict[tuple, np.ndarray] = {}
        self.runs: dict[tuple[int, int], np.ndarray] = {}
        self.dirty: tuple[int, int, int, int] | None = None

    def reset(self) -> None:
        if self.dirty is not None:
            y0, y1, x0, x1 = self.dirty
            self.best_zd[y0:y1, x0:x1] = np.inf
            self.best_id[y0:y1, x0:x1] = -1
            self.dirty = None

    def projection(self, mh: int, mw: int) -> Projection:
        if (mh, mw) not in self.projections:
            self.projections[mh, mw] = Projection.empty(mh, mw)
        return self.projections[mh, mw]

    def fixed_radii(self, n: int, mode) -> np.ndarray:
        key = (n, str(mode))
        if key not in self.radii:
            self.radii[key] = (np.empty(n, np.int8) if mode == "adaptive"
                               else np.full(n, (int(mode) - 1) // 2, np.int8))
        return self.radii[key]

    def raster_runs(self, mh: int, mw: int) -> np.ndarray:
        if (mh, mw) not in self.runs:
            self.runs[mh, mw] = raster_runs(mh, mw)
        return self.runs[mh, mw]


def stencil_box(stencil: np.ndarray):
    """(rows holding a stencil pixel, (x0, x1, y0, y1) box) or (rows, None) if empty."""
    ys = np.flatnonzero(stencil.any(axis=1))
    if ys.size == 0:
        return ys, None
    xs = np.flatnonzero(stencil[ys[0]:ys[-1] + 1].any(axis=0))
    return ys, (int(xs[0]), int(xs[-1]) + 1, int(ys[0]), int(ys[-1]) + 1)


def warp_maps(maps, camera: Camera, reflection: np.ndarray, mirrored_eye: np.ndarray,
              stencil: np.ndarray, splat_mode, ordered: bool,
              buffers: WarpBuffers | None = None):
    """Warp several zexel maps (ZexelMap) into the pixels of `stencil` seen from `camera`.

    Returns (depth (H, W) float32, id (H, W) int64: map index * stride + zexel index, or -1
    where no zexel landed, stride, zexels projected into the stencil's box). With `buffers`
    the results are views of its arrays, valid until its next use."""
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
    return warp_depths(items, camera.near, stencil, splat_mode, ordered, buffers)


def warp_depths(items, near: float, stencil: np.ndarray, splat_mode, ordered: bool,
                buffers: WarpBuffers | None = None):
    """warp_maps on (depth (mh, mw) float32, W (4, 4) map pixel -> clip, runs or None for
    row-major order) per map: the kernels without the cameras."""
    h, w = stencil.shape
    if buffers is None:
        buffers = WarpBuffers(h, w)
    buffers.reset()
    best_zd, best_id = buffers.best_zd, buffers.best_id
    best_z = best_zd[:, :, 0]
    stride = max(depth.size for depth, _, _ in items)
    ys, box = stencil_box(stencil)
    if box is None:
        return best_z, best_id, stride, 0
    x0, x1, y0, y1 = box
    buffers.dirty = (y0, y1, x0, x1)
    # zexels landing this far outside the stencil's box cannot splat into it
    margin = 8 if splat_mode == "adaptive" else 3
    zexels = 0
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
    return best_z, best_id, stride, zexels


def gather_colors(best_id: np.ndarray, stride: int, per_map: list[np.ndarray],
                  box: tuple[int, int, int, int], out: np.ndarray) -> None:
    """out[y, x] = the row of per_map[slot] (each (n, c)) for the warp id at each pixel of
    `box` = (x0, x1, y0, y1) that a zexel reached (id = slot * stride + index); other pixels
    of the box are left alone. Up to four maps a pass (one signature for any count)."""
    x0, x1, y0, y1 = box
    for first in range(0, len(per_map), 4):
        group = per_map[first:first + 4]
        group = group + [group[0]] * (4 - len(group))
        _gather4(best_id, stride, first, len(per_map[first:first + 4]), group[0], group[1],
                 group[2], group[3], x0, x1, y0, y1, out)


@njit(cache=True, parallel=True)
def _gather4(best_id, stride, first, n, c0, c1, c2, c3, x0, x1, y0, y1, out):
    channels = out.shape[2]
    for y in prange(y0, y1):
        for x in range(x0, x1):
            ident = best_id[y, x]
            if ident < 0:
                continue
            slot = ident // stride - first
            if slot < 0 or slot >= n:
                continue
            k = ident - (slot + first) * stride
            src = c0 if slot == 0 else c1 if slot == 1 else c2 if slot == 2 else c3
            for c in range(channels):
                out[y, x, c] = src[k, c]


@njit(cache=True, parallel=True)
def fill_blend(stencil, best_id, reflected, has_prev, prev_rgb, prev_filled, temporal,
                save_rgb, save_filled, background, reflectance, rgb, holes):
    """Per mirror pixel: the warped color, else (temporal) the previous frame's, else the
    background (a hole); rgb += reflectance * that. With `temporal`, save_rgb/save_filled
    receive this frame's reflected colors and filled pixels for the next frame."""
    h, w = stencil.shape
    for y in prange(h):
        for x in range(w):
            if not stencil[y, x]:
                if temporal:
                    save_filled[y, x] = False
                continue
            filled = best_id[y, x] >= 0
            if not filled and has_prev and prev_filled[y, x]:
                for c in range(3):
                    reflected[y, x, c] = prev_rgb[y, x, c]
                filled = True
            if temporal:
                save_filled[y, x] = filled
                if filled:
                    for c in range(3):
                        save_rgb[y, x, c] = reflected[y, x, c]
            if not filled:
                for c in range(3):
                    reflected[y, x, c] = background[c]
                holes[y, x] = 1.0
            for c in range(3):
                rgb[y, x, c] += reflectance[c] * reflected[y, x, c]
