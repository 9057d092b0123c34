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
z-testing only against other maps. Both run one band of screen rows per task (balanced by
zexel count) over zexels skipping map rows that cannot reach it, so results do not depend
on the thread count (the order within a band is fixed: map rows in run order).

Fixed splats wider than a pixel in z-buffer mode are a `spread` of the one-pixel result:
over its (2r + 1)^2 square a pixel keeps its own zexel if that is on the square's front
surface, else the nearest kept zexel (least (depth, id): a separable minimum over packed
integer keys, as a z-buffered splat of the one-pixel result would) of the smallest square
around it (radius 1, 2, ..., r) whose nearest is on that front surface;
adaptive splats and ordered wide ones splat each zexel over its square (`splat`).

The projection is float32 throughout (one 4x4 from map pixel to homogeneous screen point,
written with selects so that it vectorizes). The one-pixel splat projects the map itself,
row by row into buffers each task keeps in cache (no projection arrays), and writes each
reached pixel's payload row (colour, triangle) as it goes, so no gather pass follows it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numba import njit, prange

from ..camera import Camera
from ..camera import screen_from_ndc as _screen_from_ndc


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


def screen_matrix(width: int, height: int) -> np.ndarray:
    """The 4x4 taking clip coordinates to homogeneous screen ones: (x, y) / w of its result
    is `camera.screen_from_ndc` of the clip point's (x, y) / w (read off that function)."""
    ox, oy = _screen_from_ndc(0.0, 0.0, width, height)
    ax, ay = _screen_from_ndc(1.0, 1.0, width, height)
    s = np.eye(4)
    s[0, 0], s[0, 3] = ax - ox, ox
    s[1, 1], s[1, 3] = ay - oy, oy
    return s


@dataclass
class Projection:
    """One map's projected zexels (reused from frame to frame for maps of one size)."""

    sx: np.ndarray  # (n,) float32 screen x, NaN: not warped
    sy: np.ndarray  # (n,) float32 screen y
    z: np.ndarray  # (n,) float32 eye depth in the target camera
    pix: np.ndarray  # (n,) int32 flat screen pixel y * width + x of the zexel, -1: not warped
    d: np.ndarray  # (n,) float32 squared distance to its pixel's center (positions=False)
    row_lo: np.ndarray  # (mh,) int64 first screen row a map row reaches
    row_hi: np.ndarray  # (mh,) int64 last screen row a map row reaches
    count: np.ndarray  # (mh,) int64 zexels of the map row that were warped

    @classmethod
    def empty(cls, mh: int, mw: int) -> Projection:
        n = mh * mw
        return cls(np.empty(n, np.float32), np.empty(n, np.float32), np.empty(n, np.float32),
                   np.empty(n, np.int32), np.empty(n, np.float32), np.empty(mh, np.int64),
                   np.empty(mh, np.int64), np.empty(mh, np.int64))


def project_map(depth: np.ndarray, w: np.ndarray, width: int, height: int, near: float,
                box: tuple[int, int, int, int] | None = None, margin: int = 3,
                out: Projection | None = None, positions: bool = True):
    """Screen positions (float32, pixels) and eye depths of every zexel, and per map row the
    first and last screen row its zexels reach (row_lo > row_hi if none). Zexels behind the
    eye or outside `box` = (x0, x1, y0, y1) grown by `margin` pixels get sx = NaN; pix is
    -1 for those and for zexels off the screen. Float32 arithmetic throughout (one 4x4 from
    map pixel to homogeneous screen point). `out`: arrays to write into (kept across
    frames), returned filled. `positions=False`: instead of sx and sy (left as they were),
    only each zexel's squared distance to its pixel's center (out.d), all a one-pixel
    splat needs."""
    if out is None:
        out = Projection.empty(*depth.shape)
    x0, x1, y0, y1 = box if box is not None else (0, width, 0, height)
    m = np.ascontiguousarray(screen_matrix(width, height) @ w, np.float32)
    _project(np.ascontiguousarray(depth, np.float32), m, near, x0 - margin, x1 + margin,
             y0 - margin, y1 + margin, width, height, positions, out.sx, out.sy, out.z, out.pix,
             out.d, out.row_lo, out.row_hi, out.count)
    return out.sx, out.sy, out.z, out.row_lo, out.row_hi


@njit(cache=True, parallel=True, error_model="numpy")
def _project(depth, m, near, xmin, xmax, ymin, ymax, width, height, positions, sx, sy, z, pix,
             dist, row_lo, row_hi, count):
    mh, mw = depth.shape
    for v in prange(mh):
        a = v * mw
        lo, hi, warped = _project_row(depth, m, v, near, xmin, xmax, ymin, ymax, width,
                                      height, positions, sx[a:a + mw], sy[a:a + mw],
                                      z[a:a + mw], pix[a:a + mw], dist[a:a + mw])
        row_lo[v] = lo if warped > 0 else 1 << 40
        row_hi[v] = hi if warped > 0 else -1
        count[v] = warped


@njit(cache=True, inline="always")
def _project_row(depth, m, v, near, xmin, xmax, ymin, ymax, width, height, positions, sx, sy, z,
                 pix, dist):
    """Map row v into the row arrays (sx, sy: with `positions`, else dist); returns (first
    row, last row, count) of its warped zexels. The homogeneous screen point (hx, hy, hw) = M
    (u, v, 1, delta), scaled by the depth d (the same point for d > 0, without dividing by
    d): hw is then the eye depth in the target camera. Written without branches (selects)
    so that the loop vectorizes."""
    mw = depth.shape[1]
    one = np.float32(1.0)
    zero = np.float32(0.0)
    inf = np.float32(np.inf)
    nan = np.float32(np.nan)
    half = np.float32(0.5)
    near32 = np.float32(near)
    fx0, fx1 = np.float32(xmin), np.float32(xmax)
    fy0, fy1 = np.float32(ymin), np.float32(ymax)
    wid = np.int32(width)
    fw, fh = np.float32(width), np.float32(height)
    vf = np.float32(v)
    r0 = m[0, 1] * vf + m[0, 2]
    r1 = m[1, 1] * vf + m[1, 2]
    r3 = m[3, 1] * vf + m[3, 2]
    a0, a1, a3 = m[0, 0], m[1, 0], m[3, 0]
    t0, t1, t3 = m[0, 3], m[1, 3], m[3, 3]
    lo = np.int32(1 << 30)
    hi = np.int32(-(1 << 30))
    warped = 0
    for u in range(mw):
        uf = np.float32(u)
        d = depth[v, u]
        finite = d < inf  # False for inf (a direction: delta = 0) and NaN
        s = d if finite else one
        t = one if finite else zero
        hx = (a0 * uf + r0) * s + t0 * t
        hy = (a1 * uf + r1) * s + t1 * t
        hw = (a3 * uf + r3) * s + t3 * t
        inv = one / hw
        x = hx * inv
        y = hy * inv
        ok = ((finite & (d > zero) & (hw > near32)) | ((d == inf) & (hw > zero))) & (
            x >= fx0) & (x < fx1) & (y >= fy0) & (y < fy1)
        xs = x if ok else zero
        ys = y if ok else zero
        px = np.int32(np.floor(xs))
        py = np.int32(np.floor(ys))
        if positions:
            sx[u] = x if ok else nan
            sy[u] = ys
        else:
            ex = xs - np.floor(xs) - half
            ey = ys - np.floor(ys) - half
            dist[u] = ex * ex + ey * ey
        z[u] = hw if finite else inf
        on_screen = ok & (xs >= zero) & (xs < fw) & (ys >= zero) & (ys < fh)
        pix[u] = py * wid + px if on_screen else np.int32(-1)
        lo = min(lo, py if ok else np.int32(1 << 30))
        hi = max(hi, py if ok else np.int32(-(1 << 30)))
        warped += 1 if ok else 0
    return lo, hi, warped


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


def splat_pixels(proj: Projection, runs, mw, base, stencil, best_zd, best_id, ordered: bool,
                 region, clear: bool, use_stencil: bool, bands: int | None = None,
                 payload=None, payload_out=None, source=None) -> None:
    """The one-pixel splat: each zexel of `proj` (visited run by run) at the pixel it lands
    in, by the visibility rule of `_write`, into best_zd (H, W, 2) float32 (depth, squared
    distance of the zexel to the pixel center) and best_id (ids base + zexel index), only
    inside `region` = (x0, x1, y0, y1) (and, with `use_stencil`, only on stencil pixels);
    `proj` must come from `project_map` with that region as its grown box (its columns are
    not checked again) and `positions=False` (the distances). `clear`: reset the region
    first (inside the kernel, each band its rows; a cleared pixel is (inf, inf), -1, which
    the rule reads as empty without looking at its id). One band of rows per task, balanced
    by zexel count; each band visits every run but skips the map rows that cannot reach it,
    so the result does not depend on the thread count. `bands`: how many (default: two a
    thread). `payload` (n, c): a row per zexel, copied into `payload_out` (H, W, c) with
    each zexel that takes a pixel (so a reached pixel ends with its kept zexel's row; other
    pixels are left alone). `source` = (depth (mh, mw), W, near, (x0, x1, y0, y1) the grown
    box): project the map inside the kernel instead (each task the rows that reach its band,
    into buffers it keeps in cache; the same arithmetic and results as `project_map` with
    that box and `positions=False`), and fill only proj's row spans and counts."""
    x0, x1, y0, y1 = region
    if bands is None:
        bands = max(1, numba.get_num_threads()) * 2
    h, w = best_id.shape
    pay, pay_out = _payload_args(payload, payload_out)
    if source is None:  # proj holds the projection
        from_depth, near, grown = False, 0.0, region
        depth, m = np.empty((1, 1), np.float32), np.empty((4, 4), np.float32)
    else:  # project here: proj receives only the rows' spans and counts
        depth, wm, near, grown = source
        from_depth = True
        depth = np.ascontiguousarray(depth, np.float32)
        m = np.ascontiguousarray(screen_matrix(w, h) @ wm, np.float32)
    _splat_pixels(proj.pix, proj.d, proj.z, runs, mw, proj.row_lo, proj.row_hi, proj.count,
                  base, ordered, stencil.reshape(-1), use_stencil, x0, x1, y0, y1, w, clear,
                  bands, best_zd.reshape(-1), best_id.reshape(-1), payload is not None, pay,
                  pay_out, from_depth, depth, m, near, grown[0], grown[1], grown[2], grown[3],
                  h)


@njit(cache=True, inline="always")
def _copy_zexel_rows(ids, rows, shift, dst, base):
    """dst[base + i] = the row of zexel ids[i] from its map, for every pixel of a row (no
    branch on which: a kept own zexel's row again, and for a pixel no zexel reached some
    row, whose value does not matter)."""
    for i in range(ids.shape[0]):
        q = max(ids[i], 0)
        slot = q >> shift
        _copy_row(rows[slot], q - (slot << shift), dst, base + i)


@njit(cache=True, inline="always")
def _copy_row(src, k, dst, p):
    """dst[p] = src[k], with the common widths (3: colour, 4: colour and triangle) as
    constant loops."""
    c = src.shape[1]
    if c == 3:
        for j in range(3):
            dst[p, j] = src[k, j]
    elif c == 4:
        for j in range(4):
            dst[p, j] = src[k, j]
    else:
        for j in range(c):
            dst[p, j] = src[k, j]


def _payload_args(payload, payload_out):
    """(payload (n, c), payload_out flattened to (H * W, c)), or empty stand-ins."""
    if payload is None:
        return np.empty((0, 1), np.float32), np.empty((0, 1), np.float32)
    if not payload_out.flags.c_contiguous:
        raise ValueError("payload_out must be C-contiguous (its rows are written in place)")
    c = payload.shape[1]
    return np.ascontiguousarray(payload), payload_out.reshape(-1, c)


@njit(cache=True, parallel=True, error_model="numpy")
def _splat_pixels(pix, dist, z, runs, mw, row_lo, row_hi, count, base, ordered, stencil,
                  use_stencil, x0, x1, y0, y1, width, clear, bands, zd, ids, with_payload, pay,
                  pay_out, from_depth, depth, m, near, xmin, xmax, ymin, ymax, height):
    # zd: (depth, squared distance) per pixel, one 8-byte record.
    # from_depth: project the map (depth, m: as `_project` with positions=False) here, row by
    # row into buffers each task keeps in cache, instead of reading pix, dist, z: first
    # every row's screen span (into row_lo, row_hi, count), then each band projects again
    # the rows that reach it (the same arithmetic: the same results)
    if from_depth:
        for v in prange(row_lo.shape[0]):
            rp = np.empty(mw, np.int32)
            rz = np.empty(mw, np.float32)
            rd = np.empty(mw, np.float32)
            lo, hi, warped = _project_row(depth, m, v, near, xmin, xmax, ymin, ymax, width,
                                          height, False, rd, rd, rz, rp, rd)
            row_lo[v] = lo if warped > 0 else 1 << 40
            row_hi[v] = hi if warped > 0 else -1
            count[v] = warped
    # band edges over rows [y0, y1): each map row's zexels counted at its middle row
    hist = np.zeros(y1 - y0 + 1, np.int64)
    total = 0
    for v in range(row_lo.shape[0]):
        if count[v] > 0:
            mid = min(max((row_lo[v] + row_hi[v]) // 2, y0), y1) - y0
            hist[mid] += count[v]
            total += count[v]
    edges = np.empty(bands + 1, np.int64)
    edges[0] = y0
    edges[bands] = y1
    acc = 0
    b = 1
    for y in range(y1 - y0):
        acc += hist[y]
        while b < bands and acc * bands >= total * b:
            edges[b] = y0 + y + 1
            b += 1
    while b < bands:
        edges[b] = y1
        b += 1
    inf = np.float32(np.inf)
    for b in prange(bands):
        r0 = edges[b]
        r1 = edges[b + 1]
        if r1 <= r0:
            continue
        if clear:
            for y in range(r0, r1):
                for p in range(y * width + x0, y * width + x1):
                    zd[2 * p] = inf
                    zd[2 * p + 1] = inf  # no zexel lands this far from a center: empty
                    ids[p] = -1
        p0 = r0 * width
        p1 = r1 * width
        bp = np.empty(mw, np.int32)
        bz = np.empty(mw, np.float32)
        bd = np.empty(mw, np.float32)
        projected = -1
        for run in range(runs.shape[0]):
            v = runs[run, 0]
            if row_hi[v] < r0 or row_lo[v] >= r1:
                continue
            if from_depth:
                if v != projected:
                    _project_row(depth, m, v, near, xmin, xmax, ymin, ymax, width, height,
                                 False, bd, bd, bz, bp, bd)
                    projected = v
                rp, rz, rd = bp, bz, bd
            else:
                rp = pix[v * mw:(v + 1) * mw]
                rz = z[v * mw:(v + 1) * mw]
                rd = dist[v * mw:(v + 1) * mw]
            for u in range(runs[run, 1], runs[run, 2], runs[run, 3]):
                p = rp[u]
                if p < p0 or p >= p1:  # also p = -1: not warped
                    continue
                if use_stencil and not stencil[p]:
                    continue
                dk = rd[u]
                zk = rz[u]
                k = v * mw + u
                ident = base + k
                cz = zd[2 * p]
                # an empty pixel (inf, inf): a finite zk is nearer, an infinite one lands
                # nearer the center; its id is read only for an exact tie or in ordered mode
                take = zk < cz * (1.0 - SAME_SURFACE)
                if not take and ordered:
                    take = ids[p] >= base
                if not take and (zk <= cz * (1.0 + SAME_SURFACE) or zk == cz):
                    cd = zd[2 * p + 1]
                    take = dk < cd
                    if dk == cd:
                        take = ident < ids[p]
                if take:
                    zd[2 * p] = zk
                    zd[2 * p + 1] = dk
                    ids[p] = ident
                    if with_payload:
                        _copy_row(pay, k, pay_out, p)


# key of no zexel in `spread`: above every (depth bits, id) key, inf depths included
_NO_KEY = np.int64(0x7FFFFFFFFFFFFFFF)


def spread(best_zd, best_id, radius: int, stencil, box, out_z, out_id, payloads=None,
           stride: int = 1, payload_out=None, bands: int | None = None) -> None:
    """A splat of (2 radius + 1)^2 pixels from the one-pixel splat's result (`best_zd` (H,
    W, 2): depth, distance; best_id). Each kept zexel has the key (float32 depth bits, id)
    (bits of a non-negative float order as the float does): of the kept zexels in the
    square around a stencil pixel of `box` = (x0, x1, y0, y1), the one with the least key
    is the nearest (ties to the lower id), and the front surface is those within
    SAME_SURFACE of its depth (or equal to it: at infinity). The pixel keeps its own zexel
    if that is on the front surface (where zexels are dense, the wide splat is the one-pixel
    one); else, of the squares of radius 1, 2, ..., radius around it, it takes the least
    key's zexel of the first whose least key is on the front surface (so a hole takes a
    near neighbour). The least key over a square is a separable minimum (over the square's
    rows, then its columns). Writes out_z / out_id over the box
    (inf / -1 off the stencil). `payloads`: per map (n, c) rows, ids slot * stride + index
    (stride a power of two); each pixel of the box gets its zexel's row in `payload_out`
    (H, W, c) (copied for every pixel, without a branch: pixels no zexel reached, or off the
    stencil, receive some row), so the one-pixel splat need not write rows."""
    x0, x1, y0, y1 = box
    if payloads is None:
        rows = (np.empty((0, 1), np.float32),)
        pay_out = rows[0]
    else:
        rows = tuple(np.ascontiguousarray(p) for p in payloads)
        _, pay_out = _payload_args(rows[0], payload_out)
    zd = np.ascontiguousarray(best_zd).reshape(-1)
    if bands is None:
        bands = max(1, numba.get_num_threads()) * 4
    _spread(zd, zd.view(np.int32), np.ascontiguousarray(best_id).reshape(-1), radius,
            stencil, x0, x1, y0, y1, best_id.shape[0], best_id.shape[1], out_z, out_id,
            payloads is not None, rows, stride.bit_length() - 1, pay_out, bands)


@njit(cache=True, parallel=True, error_model="numpy")
def _spread(zd, bits, idf, r, stencil, x0, x1, y0, y1, h, w, out_z, out_id, with_payload, rows,
            shift, pay_out, bands):
    # bands of rows, each run top to bottom with a ring of the 2r + 1 rows' keys around its
    # row (each pixel's key made once a band); a pixel's result depends on its square only
    for b in prange(bands):
        ya = y0 + (y1 - y0) * b // bands
        yb = y0 + (y1 - y0) * (b + 1) // bands
        if yb <= ya:
            continue
        # the common radii as constants: their loops unroll
        if r == 1:
            _spread_band(zd, bits, idf, 1, stencil, x0, x1, ya, yb, h, w, out_z, out_id,
                         with_payload, rows, shift, pay_out)
        elif r == 2:
            _spread_band_rings(zd, bits, idf, 2, stencil, x0, x1, ya, yb, h, w, out_z, out_id,
                               with_payload, rows, shift, pay_out)
        else:
            _spread_band_rings(zd, bits, idf, r, stencil, x0, x1, ya, yb, h, w, out_z, out_id,
                               with_payload, rows, shift, pay_out)


@njit(cache=True, inline="always")
def _spread_band(zd, bits, idf, r, stencil, x0, x1, ya, yb, h, w, out_z, out_id, with_payload,
                 rows, shift, pay_out):
    """Rows [ya, yb) of `spread`. Neighbours off the screen are replaced by the nearest pixel
    on it (clamped coordinates): a pixel counted twice changes no minimum."""
    xa = max(x0 - r, 0)
    n_col = min(x1 + r, w) - xa
    n = x1 - x0
    size = 2 * r + 1
    ring = np.empty((size, n_col), np.int64)  # ring[(yy + r) % size]: keys of row clamp(yy)
    for yy in range(ya - r, ya + r):
        _key_row(ring[(yy + r) % size], bits, idf, min(max(yy, 0), h - 1) * w + xa)
    padded = np.full(n_col + 2 * r, _NO_KEY, np.int64)
    least = np.empty(n, np.int64)
    front_bits = np.empty(n, np.int32)
    front = front_bits.view(np.float32)
    for y in range(ya, yb):
        _key_row(ring[(y + 2 * r) % size], bits, idf, min(y + r, h - 1) * w + xa)
        # the square's least key: a column minimum over its rows (into a row padded with no
        # key: the clamped columns repeat an edge column already in the square), then a row
        # minimum
        column = padded[r:r + n_col]  # column[i]: screen column xa + i
        column[:] = ring[0]
        for j in range(1, size):
            _min_into(column, ring[j])
        least[:] = padded[x0 - xa:x0 - xa + n]
        for dx in range(1, 2 * r + 1):
            _min_into(least, padded[x0 - xa + dx:x0 - xa + dx + n])
        for i in range(n):  # the least key's depth, as float32 (its high bits)
            front_bits[i] = np.int32(least[i] >> 32)
        # a pixel whose own zexel is on the front surface keeps it (no branches); the others
        # (holes of the one-pixel splat, or behind a nearer neighbour) take the least key's
        base = y * w + x0
        _spread_pick(zd[2 * base:2 * (base + n)], idf[base:base + n], least, front,
                     stencil[y, x0:x1], out_z[y, x0:x1], out_id[y, x0:x1])
        if with_payload:  # each pixel's zexel's row from its map
            _copy_zexel_rows(out_id[y, x0:x1], rows, shift, pay_out, base)


@njit(cache=True, inline="always")
def _spread_pick(zd, own, least, front, on, oz, oi):
    """One row's choice: own zexel if on the front surface, else the least key's."""
    inf = np.float32(np.inf)
    for i in range(own.shape[0]):
        zo = zd[2 * i]
        fz = front[i]
        keep = (own[i] >= 0) & ((zo <= fz * (1.0 + SAME_SURFACE)) | (zo == fz))
        key = least[i]
        found = key != _NO_KEY
        z_other = fz if found else inf
        id_other = (key & 0xFFFFFFFF) if found else np.int64(-1)
        z_pick = zo if keep else z_other
        id_pick = own[i] if keep else id_other
        oz[i] = z_pick if on[i] else inf
        oi[i] = id_pick if on[i] else np.int64(-1)


@njit(cache=True, inline="always")
def _spread_band_rings(zd, bits, idf, r, stencil, x0, x1, ya, yb, h, w, out_z, out_id,
                       with_payload, rows, shift, pay_out):
    """`_spread_band` for r > 1: a hole takes the least key of the smallest square around
    it whose least key is on the front surface (its own function: in `_spread_band` the
    squares' loop slows r = 1 by a fifth)."""
    xa = max(x0 - r, 0)
    n_col = min(x1 + r, w) - xa
    n = x1 - x0
    size = 2 * r + 1
    ring = np.empty((size, n_col), np.int64)  # ring[(yy + r) % size]: keys of row clamp(yy)
    for yy in range(ya - r, ya + r):
        _key_row(ring[(yy + r) % size], bits, idf, min(max(yy, 0), h - 1) * w + xa)
    padded = np.full(n_col + 2 * r, _NO_KEY, np.int64)
    least = np.empty(n, np.int64)
    pick = np.empty(n, np.int64)
    inner = np.empty((max(r - 1, 1), n), np.int64)  # inner[k - 1]: squares of radius k < r
    front_bits = np.empty(n, np.int32)
    front = front_bits.view(np.float32)
    pick_bits = np.empty(n, np.int32)
    pick_z = pick_bits.view(np.float32)
    for y in range(ya, yb):
        _key_row(ring[(y + 2 * r) % size], bits, idf, min(y + r, h - 1) * w + xa)
        # the least key of the square of radius k = 1..r around each pixel: a column
        # minimum over its rows (into a row padded with no key: the clamped columns repeat an
        # edge column already in the square), then a row minimum. `least` ends with the
        # whole square's (the front surface's depth), `pick` with the smallest square's
        # whose least key is on that front surface
        column = padded[r:r + n_col]  # column[i]: screen column xa + i
        base = y * w + x0
        column[:] = ring[(y + r) % size]
        for k in range(1, r + 1):
            _min_into(column, ring[(y + r - k) % size])
            _min_into(column, ring[(y + r + k) % size])
            ring_least = least if k == r else inner[k - 1]
            ring_least[:] = padded[x0 - xa + r - k:x0 - xa + r - k + n]
            for dx in range(r - k + 1, r + k + 1):
                _min_into(ring_least, padded[x0 - xa + dx:x0 - xa + dx + n])
        for i in range(n):  # the least key's depth, as float32 (its high bits)
            front_bits[i] = np.int32(least[i] >> 32)
        pick[:] = least
        for k in range(r - 1, 0, -1):  # smaller squares win where on the front surface
            _nearer_ring(pick, inner[k - 1], front, pick_bits)
        for i in range(n):  # the picked key's depth
            pick_bits[i] = np.int32(pick[i] >> 32)
        # the same choice, with the picked key instead of the least
        _spread_pick_ring(zd[2 * base:2 * (base + n)], idf[base:base + n], pick, front, pick_z,
                          stencil[y, x0:x1], out_z[y, x0:x1], out_id[y, x0:x1])
        if with_payload:  # each pixel's zexel's row from its map
            _copy_zexel_rows(out_id[y, x0:x1], rows, shift, pay_out, base)


@njit(cache=True, inline="always")
def _spread_pick_ring(zd, own, pick, front, pick_z, on, oz, oi):
    """`_spread_pick` with the picked key's depth given (a smaller square's key)."""
    inf = np.float32(np.inf)
    for i in range(own.shape[0]):
        zo = zd[2 * i]
        fz = front[i]
        keep = (own[i] >= 0) & ((zo <= fz * (1.0 + SAME_SURFACE)) | (zo == fz))
        key = pick[i]
        found = key != _NO_KEY
        z_other = pick_z[i] if found else inf
        id_other = (key & 0xFFFFFFFF) if found else np.int64(-1)
        z_pick = zo if keep else z_other
        id_pick = own[i] if keep else id_other
        oz[i] = z_pick if on[i] else inf
        oi[i] = id_pick if on[i] else np.int64(-1)


@njit(cache=True, inline="always")
def _nearer_ring(pick, ring_least, front, scratch):
    """pick[i] = ring_least[i] where that key's depth is on the front surface (`scratch`: an
    int32 row for the depths' bits)."""
    for i in range(pick.shape[0]):
        scratch[i] = np.int32(ring_least[i] >> 32)
    z = scratch.view(np.float32)
    for i in range(pick.shape[0]):
        key = ring_least[i]
        f = front[i]
        on = (key != _NO_KEY) & ((z[i] <= f * (1.0 + SAME_SURFACE)) | (z[i] == f))
        pick[i] = key if on else pick[i]


@njit(cache=True, inline="always")
def _key_row(dst, bits, idf, start):
    """dst[i] = key of pixel start + i: (depth bits << 32) | id, or no key."""
    n = dst.shape[0]
    b = bits[2 * start:2 * (start + n)]
    q = idf[start:start + n]
    for i in range(n):
        key = (np.int64(b[2 * i]) << 32) | (q[i] & 0xFFFFFFFF)
        dst[i] = key if q[i] >= 0 else _NO_KEY


@njit(cache=True, inline="always")
def _min_into(acc, values):
    for i in range(acc.shape[0]):
        v = values[i]
        acc[i] = v if v < acc[i] else acc[i]


class WarpBuffers:
    """The warp's per-frame arrays, kept across frames: page faults on fresh arrays cost more
    than the warp itself. Everything the warp writes into best_zd / best_id lies in `dirty`
    = (x0, x1, y0, y1), into out_z / out_id in `dirty_out`; a later use resets what it will
    not overwrite itself (outside them the buffers stay clear)."""

    def __init__(self, height: int, width: int) -> None:
        self.shape = (height, width)
        self.best_zd = np.full((height, width, 2), np.inf, np.float32)
        self.best_id = np.full((height, width), -1, np.int64)
        self.out_z = np.full((height, width), np.inf, np.float32)
        self.out_id = np.full((height, width), -1, np.int64)
        self.projections: dict[tuple[int, int], Projection] = {}
        self.radii: dict[tuple, np.ndarray] = {}
        self.runs: dict[tuple[int, int], np.ndarray] = {}
        self.dirty: tuple[int, int, int, int] | None = None
        self.dirty_out: tuple[int, int, int, int] | None = None

    def claim(self, region, written=None) -> None:
        """Reset best_zd / best_id where the last use wrote and `written` (the region the
        caller clears or overwrites itself, or None) does not cover; mark `region` dirty."""
        if self.dirty is not None and not _covers(written, self.dirty):
            x0, x1, y0, y1 = self.dirty
            self.best_zd[y0:y1, x0:x1] = np.inf
            self.best_id[y0:y1, x0:x1] = -1
        self.dirty = region

    def claim_out(self, box) -> None:
        """The same for out_z / out_id, which `spread` overwrites over `box`."""
        if self.dirty_out is not None and not _covers(box, self.dirty_out):
            x0, x1, y0, y1 = self.dirty_out
            self.out_z[y0:y1, x0:x1] = np.inf
            self.out_id[y0:y1, x0:x1] = -1
        self.dirty_out = box

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


def _covers(outer, inner) -> bool:
    """Box `outer` (x0, x1, y0, y1, or None) contains box `inner`."""
    return outer is not None and (outer[0] <= inner[0] and inner[1] <= outer[1]
                                  and outer[2] <= inner[2] and inner[3] <= outer[3])


def stencil_box(stencil: np.ndarray):
    """(rows holding a stencil pixel, (x0, x1, y0, y1) box) or (rows, None) if empty."""
    ys = np.flatnonzero(stencil.any(axis=1))
    if ys.size == 0:
        return ys, None
    xs = np.flatnonzero(stencil[ys[0]:ys[-1] + 1].any(axis=0))
    return ys, (int(xs[0]), int(xs[-1]) + 1, int(ys[0]), int(ys[-1]) + 1)


def warp_maps(maps, camera: Camera, reflection: np.ndarray, mirrored_eye: np.ndarray,
              stencil: np.ndarray, splat_mode, ordered: bool,
              buffers: WarpBuffers | None = None, box=None, payloads=None, out=None):
    """Warp several zexel maps (ZexelMap) into the pixels of `stencil` seen from `camera`.

    Returns (depth (H, W) float32, id (H, W) int64: map index * stride + zexel index, or -1
    where no zexel landed, stride, zexels projected into the stencil's box). With `buffers`
    the results are views of its arrays, valid until its next use. `box`, `payloads`, `out`:
    as for warp_depths."""
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
        # a stencil filling its box (a mirror seen whole and unoccluded) needs no test
        use_stencil = radius == 0 and not stencil[y0:y1, x0:x1].all()
        region = (max(x0 - radius, 0), min(x1 + radius, w), max(y0 - radius, 0),
                  min(y1 + radius, h))
        buffers.claim(region, region)
        for slot, (depth, wm, runs) in enumerate(items):
            mh, mw = depth.shape
            proj = buffers.projection(mh, mw)
            if runs is None:
                runs = buffers.raster_runs(mh, mw)
            # projected inside the splat: zexels beyond the region cannot reach the box
            splat_pixels(proj, runs, mw, slot * stride, stencil, buffers.best_zd,
                         buffers.best_id, ordered, region, slot == 0, use_stencil,
                         # a spread copies every pixel's row itself
                         payload=None if payloads is None or radius > 0 else payloads[slot],
                         payload_out=out,
                         source=(depth, wm, near, (x0 - radius, x1 + radius, y0 - radius,
                                                   y1 + radius)))
            zexels += int(proj.count.sum())
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


def gather_colors(best_id: np.ndarray, stride: int, per_map: list[np.ndarray],
                  box: tuple[int, int, int, int], out: np.ndarray) -> None:
    """out[y, x] = the row of per_map[slot] (each (n, c)) for the warp id at each pixel of
    `box` = (x0, x1, y0, y1) that a zexel reached (id = slot * stride + index); other pixels
    of the box are left alone. Up to four maps a pass (one signature for any count)."""
    x0, x1, y0, y1 = box
    shift = stride.bit_length() - 1 if stride & (stride - 1) == 0 else -1
    for first in range(0, len(per_map), 4):
        group = per_map[first:first + 4]
        group = group + [group[0]] * (4 - len(group))
        _gather4(best_id, stride, shift, first, len(per_map[first:first + 4]), group[0],
                 group[1], group[2], group[3], x0, x1, y0, y1, out)


@njit(cache=True, parallel=True)
def _gather4(best_id, stride, shift, first, n, c0, c1, c2, c3, x0, x1, y0, y1, out):
    # shift >= 0: stride = 2^shift, the slot without a division
    channels = out.shape[2]
    for y in prange(y0, y1):
        for x in range(x0, x1):
            ident = best_id[y, x]
            if ident < 0:
                continue
            if shift >= 0:
                s = ident >> shift
                k = ident & (stride - 1)
            else:
                s = ident // stride
                k = ident - s * stride
            slot = s - first
            if slot < 0 or slot >= n:
                continue
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
