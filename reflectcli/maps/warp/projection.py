"""The warp's projection: one float32 4x4 from map pixel (u, v, 1, delta) to homogeneous
screen point per map and frame, applied row by row in loops written with selects so that
they vectorize."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit, prange

from ...camera import Camera
from ...camera import screen_from_ndc as _screen_from_ndc


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


@lru_cache(maxsize=16)
def screen_matrix_cached(width: int, height: int) -> np.ndarray:
    """`screen_matrix`, made once a screen size (read-only): the warp asks for it every
    frame."""
    s = screen_matrix(width, height)
    s.flags.writeable = False
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
    m = np.ascontiguousarray(screen_matrix_cached(width, height) @ w, np.float32)
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


@njit(cache=True, inline="always")
def _row_reach(depth_bits, m, v, ymin, ymax):
    """(first, last, count, spread first, spread last): screen rows [ymin, ymax) that map row
    v's zexels can reach, and how many have a usable depth (positive: finite or infinite),
    bounded without projecting them (a superset of `_project_row`'s rows, for skipping rows
    a band cannot receive); and the rows they spread over, not limited to [ymin, ymax) nor
    grown by the margin (where zexels land, for weighing bands: only an estimate).
    `depth_bits`: the depths' float32 bits as int32 (positive floats order as their bits
    do: integer minima vectorize, float ones do not).

    With delta = 1 / depth (0 at infinity), screen y = (a1 u + r1 + t1 delta) / (a3 u + r3 +
    t3 delta): where the denominator stays positive over the box u in [0, mw - 1], delta in
    the row's [delta_lo, delta_hi], y is monotonic in u and in delta apart, so its extremes
    are at the box's corners. Else (the row crosses the eye plane) every row may be reached.
    Corners in float64, one row of margin each side for the kernel's float32 rounding."""
    mw = depth_bits.shape[1]
    inf_bits = np.int32(0x7F800000)
    no_min = np.int32(0x7FFFFFFF)
    zero = np.int32(0)
    b_min = no_min
    b_max = zero
    n_inf = np.int32(0)
    n_finite = np.int32(0)
    for u in range(mw):
        b = depth_bits[v, u]
        finite = (b > zero) & (b < inf_bits)  # positive and finite (NaN bits lie above inf's)
        b_min = min(b_min, b if finite else no_min)
        b_max = max(b_max, b if finite else zero)
        n_finite += np.int32(finite)
        n_inf += np.int32(b == inf_bits)
    usable = np.int64(n_finite) + np.int64(n_inf)
    lo, hi = ymin, ymax - 1
    if usable == 0:
        return lo, hi, 0, lo, hi
    # the float32 values of those bits, exactly: 2^(e - 150) (2^23 + mantissa), subnormal: e 1
    e_min, e_max = max(b_min >> 23, 1), max(b_max >> 23, 1)
    d_min = math.ldexp(np.float64((b_min & 0x7FFFFF) | (0x800000 if b_min >> 23 else 0)),
                       e_min - 150)
    d_max = math.ldexp(np.float64((b_max & 0x7FFFFF) | (0x800000 if b_max >> 23 else 0)),
                       e_max - 150)
    delta_hi = 1.0 / d_min if n_finite > 0 else 0.0
    delta_lo = 0.0 if n_inf > 0 else 1.0 / d_max
    vf = np.float64(v)
    r1 = np.float64(m[1, 1]) * vf + np.float64(m[1, 2])
    r3 = np.float64(m[3, 1]) * vf + np.float64(m[3, 2])
    y_min = np.inf
    y_max = -np.inf
    positive = True
    for corner in range(4):
        uf = 0.0 if corner < 2 else np.float64(mw - 1)
        delta = delta_lo if corner % 2 == 0 else delta_hi
        num = np.float64(m[1, 0]) * uf + r1 + np.float64(m[1, 3]) * delta
        den = np.float64(m[3, 0]) * uf + r3 + np.float64(m[3, 3]) * delta
        positive = positive and den > 0.0
        y = num / den if den > 0.0 else 0.0
        y_min = min(y_min, y)
        y_max = max(y_max, y)
    first, last = lo, hi
    if positive and np.isfinite(y_min) and np.isfinite(y_max) and y_min > -1e9 and y_max < 1e9:
        first = np.int64(math.floor(y_min))
        last = np.int64(math.floor(y_max))
        lo = max(lo, first - 1)
        hi = min(hi, last + 1)
    return lo, hi, usable, first, last
