"""Tile culling for the screen-space refinement: a reflector part's pixels in square tiles,
each bounding where its reflected rays go, so that points no ray of the part can reach are
skipped and the others get a seed pixel near their reflection."""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

from ..fused import fma
from ..parallel import claim, counter
from ..raster.rasterize.buffers import read_only, scratch


class PartTiles:
    """A part's pixels in square tiles, each with a bound on where its reflected rays go:
    (center, radius) of its points Q and (axis, half-angle) of its directions R. A ray from
    Q along R through P leaves P - center within asin(radius / |P - center|) of R, and R is
    within the half-angle of the axis, so a point outside every tile's cone is reflected
    nowhere in the part. The search samples Q and R bilinearly from 2x2 blocks of pixels,
    which may straddle tiles: each tile's bound therefore also takes in the pixel row above
    and the column left of it, so that every block lies within one tile's pixels (whose ball
    and cone, being convex, hold the block's blends); the margin covers rounding."""

    def __init__(self, inside: np.ndarray, q: np.ndarray, r: np.ndarray, size: int = 12,
                 margin_degrees: float = 1.0, tiles: np.ndarray | None = None,
                 part: int | None = None) -> None:
        """`inside` (H, W): bool, the part's pixels; or, with `part`, an owner plane (int,
        the part under each pixel: view.part_views), the part's pixels where it is `part`.
        `tiles`: the ids ty * (W // size + 1) + tx of the tiles holding a pixel of the
        part, ascending, if already known (view.part_views marks them in its pass)."""
        owner, part = owner_plane(inside, part)
        h, w = owner.shape
        if tiles is None:
            ys, xs = np.nonzero(owner == part)
            tiles = np.unique((ys // size) * (w // size + 1) + xs // size)
        n = tiles.size
        bounds = (np.empty((n, 3)), np.empty(n), np.empty((n, 3)), np.empty(n),
                  np.empty((n, 2)))
        _tile_bounds(owner, np.full(n, part, np.int64), q, r, np.asarray(tiles, np.int64),
                     size, *bounds)
        self._set(bounds, margin_degrees, _parts_balls(*bounds[:4], np.array([0, n]))[0])

    @classmethod
    def of_parts(cls, owner: np.ndarray, q: np.ndarray, r: np.ndarray, size: int,
                 tiles: list[np.ndarray], margin_degrees: float = 1.0) -> list[PartTiles]:
        """[PartTiles(owner, q, r, size, margin_degrees, tiles[p], part=p) for each p],
        every part's tile bounds in one parallel region, and their balls and cones in one
        kernel (the same bounds: each tile's are its own; each part's ball and cone are
        its tiles')."""
        counts = [len(t) for t in tiles]
        n = sum(counts)
        bounds = (np.empty((n, 3)), np.empty(n), np.empty((n, 3)), np.empty(n),
                  np.empty((n, 2)))
        _tile_bounds(owner, np.repeat(np.arange(len(tiles), dtype=np.int64), counts), q, r,
                     np.concatenate(tiles).astype(np.int64), size, *bounds)
        starts = np.zeros(len(tiles) + 1, np.int64)
        starts[1:] = np.cumsum(counts)
        balls = _parts_balls(*bounds[:4], starts)
        out = []
        for p in range(len(tiles)):
            part = cls.__new__(cls)
            part._set(tuple(b[starts[p]:starts[p + 1]] for b in bounds), margin_degrees,
                      balls[p])
            out.append(part)
        return out

    def _set(self, bounds: tuple, margin_degrees: float, ball: tuple) -> None:
        """The tiles' bounds (center, radius, axis, half, pixel: _tile_bounds), and the
        part's ball and cone holding them (_parts_balls)."""
        self.center, self.radius, self.axis, self.half, self.pixel = bounds
        self.margin = math.radians(margin_degrees)
        # one ball and cone holding every tile's (with their margins): a point outside the
        # part's cone is outside every tile's (see candidates)
        self.part_center, self.part_radius, self.part_axis, self.part_half = ball

    def candidates(self, points: np.ndarray) -> np.ndarray:
        """(N,) bool: points the part's ball and cone may reach; the others are reached by
        no tile. A tile's test holds exactly the points some ray from its ball along a
        direction of its cone passes (or its ball, grown by 0.1%); each such ray starts in the
        part's ball along a direction of the part's cone, so the same test with the part's
        ball and cone holds the point too (with 1e-9 to spare for rounding)."""
        points = np.ascontiguousarray(points, np.float64)
        out = np.empty(points.shape[0], np.bool_)
        a = self.part_half + self.margin
        _candidates(points, self.part_center, self.part_radius, self.part_axis, math.cos(a),
                    math.sin(a), a, out)
        return out

    def scan(self, points: np.ndarray, q: np.ndarray, r: np.ndarray,
             polygons: np.ndarray | None = None):
        """(reach (N,) bool: some tile's cone holds the point; seeds (N, 2): the middle pixel
        of the tile whose ray passes closest to it, among the tiles that reach it, else
        among all). With `polygons` (T, 3) point indices, seeds are found only for the
        points a part needs: those that reach it and those a polygon joins to one that does
        (NaN elsewhere); points outside the part's own cone skip the per-tile tests."""
        reach, seeds, _ = self.scan_needed(points, q, r, polygons)
        return reach, seeds

    def scan_needed(self, points: np.ndarray, q: np.ndarray, r: np.ndarray,
                    polygons: np.ndarray | None = None):
        """scan's (reach, seeds), and (N,) bool the points the part needs: with `polygons`,
        those that reach it and those a polygon joins to one that does (joined); without,
        all. Two passes: the tiles reaching each point first (blocks of points skip the
        tiles whose cone holds none of them, _scan_reached); then, among all tiles, the
        seeds of the points needed but reached by none (_scan)."""
        n = points.shape[0]
        # read-only, as a tessellation's points: the kernels compile once
        points = read_only(points, np.float64)
        reach = np.zeros(n, np.bool_)
        seeds = np.full((n, 2), np.nan)
        if polygons is None:
            self._scan_rows(points, q, r, np.arange(n), reach, seeds, reached_only=True)
            self._scan_rows(points, q, r, np.flatnonzero(~reach), reach, seeds)
            return reach, seeds, np.ones(n, np.bool_)
        # points outside the part's cone reach no tile: reach is final after the first pass
        near = self.candidates(points)
        self._scan_rows(points, q, r, np.flatnonzero(near), reach, seeds, reached_only=True)
        todo = joined(reach, polygons)
        self._scan_rows(points, q, r, np.flatnonzero(todo & ~reach), reach, seeds)
        return reach, seeds, todo

    def _scan_rows(self, points, q, r, rows, reach, seeds, reached_only=False) -> None:
        """_scan of points[rows] into reach[rows] and seeds[rows] (each point's answer is its
        own: a subset gives the same answers); `reached_only`: _scan_reached (seeds only
        where a tile reaches the point, left as they are elsewhere)."""
        if rows.size == 0:
            return
        args = (points, rows, self.center, self.radius, self.axis, self.half, self.pixel,
                self.margin, q, r, reach, seeds)
        if reached_only:
            _scan_reached(*args, numba.get_num_threads())
        else:
            _scan(*args)


def owner_plane(inside: np.ndarray, part: int | None) -> tuple[np.ndarray, int]:
    """(owner plane, part) the kernels take: `inside` as it is with `part`, else a bool
    mask seen as int8 (no copy), its pixels part 1."""
    if part is not None:
        return inside, int(part)
    return np.asarray(inside, np.bool_).view(np.int8), 1


def joined(flag: np.ndarray, polygons: np.ndarray) -> np.ndarray:
    """(N,) bool: `flag`, and every point of a polygon (T, 3 point indices) one of whose
    points has it."""
    out = flag.copy()
    _join(flag, np.ascontiguousarray(polygons, np.int64), out)
    return out


@njit(cache=True)
def _join(flag, polygons, out):
    for t in range(polygons.shape[0]):
        a, b, c = polygons[t, 0], polygons[t, 1], polygons[t, 2]
        if flag[a] or flag[b] or flag[c]:
            out[a] = True
            out[b] = True
            out[c] = True


@njit(cache=True, error_model="numpy")
def _candidates(points, center, radius, axis, cos_a, sin_a, a, out):
    """PartTiles.candidates per point: outside the ball (radius) and the cone (axis, half-angle
    a) grown by the ball's spread, with 1e-9 to spare; cos_a, sin_a of a. One thread: a few
    ns a point, less than a parallel loop's start on a busy machine."""
    for k in range(points.shape[0]):
        out[k] = _candidate(points, k, center, radius, axis, cos_a, sin_a, a)


@njit(cache=True, inline="always", error_model="numpy")
def _candidate(points, k, center, radius, axis, cos_a, sin_a, a):
    """_candidates' test of point k."""
    v0 = points[k, 0] - center[0]
    v1 = points[k, 1] - center[1]
    v2 = points[k, 2] - center[2]
    dist = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    sin_s = min(radius / dist, 1.0)
    c = (v0 * axis[0] + v1 * axis[1] + v2 * axis[2]) / dist
    bound = cos_a * math.sqrt(1.0 - sin_s * sin_s) - sin_a * sin_s
    if not (c < bound - 1e-9) or dist <= radius or sin_s >= 1.0:
        return True
    # only then the arcsine (a call, the test's costliest part)
    return a >= 0.5 * math.pi and a + math.asin(sin_s) >= math.pi


def _parts_balls(center: np.ndarray, radius: np.ndarray, axis: np.ndarray, half: np.ndarray,
                 starts: np.ndarray) -> list[tuple]:
    """Per part (its tiles rows starts[p] .. starts[p + 1] of _tile_bounds' arrays): (ball
    center (3,), ball radius, unit cone axis (3,), cone half-angle) holding every tile's
    ball and cone (_balls)."""
    parts = starts.shape[0] - 1
    ball_center, ball_radius = np.empty((parts, 3)), np.empty(parts)
    ball_axis, ball_half = np.empty((parts, 3)), np.empty(parts)
    _balls(center, radius, axis, half, starts, ball_center, ball_radius, ball_axis, ball_half)
    return [(ball_center[p], float(ball_radius[p]), ball_axis[p], float(ball_half[p]))
            for p in range(parts)]


@njit(cache=True, error_model="numpy")
def _balls(center, radius, axis, half, starts, ball_center, ball_radius, ball_axis,
           ball_half):
    """Part p's ball and cone over its tiles (rows starts[p] ..): the ball about the tiles'
    mean center, reaching the farthest tile ball (its radius grown by 0.1%, the whole by
    1e-9 for rounding); the cone about the unit sum of the tiles' axes, as wide as the
    widest tile cone seen from it (+ 1e-9); with no tile, or axes summing to zero, the
    whole sphere of directions. The numbers of numpy's whole-array version (about 15
    numpy calls a part, 14 parts a mask frame) in its order of operations: sums over rows
    in order, norms' squares summed in order, the axes' dot products as OpenBLAS's
    matrix-vector product sums them (fma(a2, u2, fma(a0, u0, a1 u1)): virtual/screen.py;
    one row, which numpy takes as a dot product, in order), numpy's arccos being the C
    library's acos on this machine kind."""
    for p in range(starts.shape[0] - 1):
        t0, t1 = starts[p], starts[p + 1]
        n = t1 - t0
        if n == 0:
            ball_center[p, 0] = ball_center[p, 1] = ball_center[p, 2] = 0.0
            ball_radius[p] = 0.0
            ball_axis[p, 0], ball_axis[p, 1], ball_axis[p, 2] = 0.0, 0.0, 1.0
            ball_half[p] = math.pi
            continue
        s0 = s1 = s2 = 0.0
        a0 = a1 = a2 = 0.0
        for j in range(t0, t1):
            s0 += center[j, 0]
            s1 += center[j, 1]
            s2 += center[j, 2]
            a0 += axis[j, 0]
            a1 += axis[j, 1]
            a2 += axis[j, 2]
        c0, c1, c2 = s0 / n, s1 / n, s2 / n
        far = -np.inf
        for j in range(t0, t1):
            d0, d1, d2 = center[j, 0] - c0, center[j, 1] - c1, center[j, 2] - c2
            far = max(far, math.sqrt((d0 * d0 + d1 * d1) + d2 * d2) + radius[j] * 1.001)
        ball_center[p, 0], ball_center[p, 1], ball_center[p, 2] = c0, c1, c2
        ball_radius[p] = far * (1 + 1e-9)
        norm = math.sqrt((a0 * a0 + a1 * a1) + a2 * a2)
        if not norm > 0:
            ball_axis[p, 0], ball_axis[p, 1], ball_axis[p, 2] = 0.0, 0.0, 1.0
            ball_half[p] = math.pi
            continue
        u0, u1, u2 = a0 / norm, a1 / norm, a2 / norm
        widest = -np.inf
        for j in range(t0, t1):
            if n == 1:  # numpy takes a single row as a dot product: summed in order
                cos = (axis[j, 0] * u0 + axis[j, 1] * u1) + axis[j, 2] * u2
            else:
                cos = fma(axis[j, 2], u2, fma(axis[j, 0], u0, axis[j, 1] * u1))
            widest = max(widest, math.acos(min(max(cos, -1.0), 1.0)) + half[j])
        ball_axis[p, 0], ball_axis[p, 1], ball_axis[p, 2] = u0, u1, u2
        ball_half[p] = widest + 1e-9


@njit(cache=True, parallel=True)
def _tile_bounds(owner, tile_part, q, r, tiles, size, center, radius, axis, half, pixel):
    """Per tile j (id tiles[j] = ty * (W // size + 1) + tx, of part tile_part[j]): over its
    part pixels (owner == part) grown
    by the row above and the column left, the ball (mean of Q, farthest Q from it), the
    cone (unit sum of R, widest angle from it) and the seed (its own pixel, not the grown
    ones, whose Q is nearest the mean; the first in row-major order on ties), as numpy's
    reductions give
    them (sums in pixel order)."""
    w = owner.shape[1]
    across = w // size + 1
    for j in prange(tiles.shape[0]):
        part = tile_part[j]
        ty, tx = divmod(tiles[j], across)
        y0, x0 = ty * size, tx * size
        ey, ex = max(y0 - 1, 0), max(x0 - 1, 0)  # grown up and left by a pixel
        y1 = min(y0 + size, owner.shape[0])
        x1 = min(x0 + size, w)
        count = 0
        s0 = s1 = s2 = 0.0
        a0 = a1 = a2 = 0.0
        for y in range(ey, y1):
            for x in range(ex, x1):
                if owner[y, x] == part:
                    count += 1
                    s0 += q[y, x, 0]
                    s1 += q[y, x, 1]
                    s2 += q[y, x, 2]
                    a0 += r[y, x, 0]
                    a1 += r[y, x, 1]
                    a2 += r[y, x, 2]
        c0, c1, c2 = s0 / count, s1 / count, s2 / count
        length = max(math.sqrt(a0 * a0 + a1 * a1 + a2 * a2), 1e-30)
        a0, a1, a2 = a0 / length, a1 / length, a2 / length
        far = 0.0
        # the widest angle is the acos of the least cosine: the C library's acos is
        # decreasing (glibc's: no pair of adjacent doubles out of order in 1.4e8 tried;
        # a test checks it), so max(acos) = acos(min) bit for bit, with one acos a tile
        # instead of one a pixel (most of the tiles' time)
        least = np.inf
        best = np.inf
        bx = by = 0
        for y in range(ey, y1):
            for x in range(ex, x1):
                if owner[y, x] != part:
                    continue
                d0, d1, d2 = q[y, x, 0] - c0, q[y, x, 1] - c1, q[y, x, 2] - c2
                dist = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                far = max(far, dist)
                cos = r[y, x, 0] * a0 + r[y, x, 1] * a1 + r[y, x, 2] * a2
                least = min(least, min(max(cos, -1.0), 1.0))
                if y >= y0 and x >= x0 and dist < best:
                    best = dist
                    bx, by = x, y
        widest = math.acos(least) if least <= 1.0 else -np.inf  # -inf: every cosine NaN
        center[j, 0], center[j, 1], center[j, 2] = c0, c1, c2
        radius[j] = far
        axis[j, 0], axis[j, 1], axis[j, 2] = a0, a1, a2
        half[j] = widest
        pixel[j, 0] = bx + 0.5
        pixel[j, 1] = by + 0.5


_BLOCK = 128  # points tested side by side against each tile


@njit(cache=True, inline="always")
def _seed_rays(pixel, margin, half, q, r):
    """Per tile: its seed pixel's Q and R (tiles, 6), and whether its cone is wide
    (half-angle at least a right angle: the spread's arcsine decides, a call that does not
    vectorise)."""
    tiles = pixel.shape[0]
    seed = np.empty((tiles, 6))
    wide = np.zeros(tiles, np.bool_)
    for j in range(tiles):
        x = int(pixel[j, 0])
        y = int(pixel[j, 1])
        for i in range(3):
            seed[j, i] = q[y, x, i]
            seed[j, 3 + i] = r[y, x, i]
        wide[j] = half[j] + margin >= 0.5 * math.pi
    return seed, wide


@njit(cache=True, inline="always")
def _load_block(points, rows, k0, count, s):
    """Rows of block s (see _scan) for points rows[k0:k0 + count], answers reset."""
    for k in range(count):
        i = rows[k0 + k]
        s[0, k] = points[i, 0]
        s[1, k] = points[i, 1]
        s[2, k] = points[i, 2]
        s[3, k] = np.inf
        s[4, k] = np.inf
        s[5, k] = -1.0
        s[6, k] = -1.0


@njit(cache=True, parallel=True, error_model="numpy")
def _scan(points, rows, center, radius, axis, half, pixel, margin, q, r, reach, seeds):
    """Per point points[rows[k]] (its answers into reach and seeds at rows[k]): the tile
    whose seed pixel's ray passes closest (least |unit(P - Q) - R|^2; the first on ties),
    among the tiles whose cone holds the point, else among all.

    Points go in blocks of _BLOCK, each block meeting the tiles one after another: the test
    of one tile against a block's points is a loop without branches, which the compiler
    vectorises (a point at a time, the tests' square roots and divisions waited on each
    other). Each point meets the tiles in the same order, with the same arithmetic, as
    one at a time."""
    n = rows.shape[0]
    cos_a = np.cos(half + margin)
    sin_a = np.sin(half + margin)
    seed, wide = _seed_rays(pixel, margin, half, q, r)
    blocks = (n + _BLOCK - 1) // _BLOCK
    for b in prange(blocks):
        _scan_block(b, points, rows, n, center, radius, axis, half, pixel, margin, cos_a,
                    sin_a, seed, wide, reach, seeds)


@njit(cache=True, inline="always", error_model="numpy")
def _scan_block(b, points, rows, n, center, radius, axis, half, pixel, margin, cos_a, sin_a,
                seed, wide, reach, seeds):
    """Block b of _scan."""
    k0 = b * _BLOCK
    count = min(n, k0 + _BLOCK) - k0
    s = np.empty((7, _BLOCK))  # x, y, z, best_in, best_any, j_in, j_any
    _load_block(points, rows, k0, count, s)
    for j in range(center.shape[0]):
        _scan_tile(s, count, j, center, radius, axis, half, margin, cos_a, sin_a, seed,
                   wide[j])
    for k in range(count):
        j_in = int(s[5, k])
        j_any = int(s[6, k])
        i = rows[k0 + k]
        reach[i] = j_in >= 0
        jj = j_in if j_in >= 0 else j_any
        if jj >= 0:
            seeds[i, 0] = pixel[jj, 0]
            seeds[i, 1] = pixel[jj, 1]


@njit(cache=True, parallel=True, error_model="numpy")
def _scan_reached(points, rows, center, radius, axis, half, pixel, margin, q, r, reach,
                  seeds, threads):
    """_scan's reach, and its seeds where a tile reaches the point (seeds left as they are
    elsewhere: no tile's ray is looked for among all), with the same answers: each block of
    points skips the tiles whose test none of its points can pass (_block_misses), so only
    tiles that hold no point of the block are left out, and the others meet each point in
    the same order, with the same arithmetic. On the mask's shell (321 tiles) 8% of the
    block-tile pairs remain. Blocks differ in cost by the tiles they keep, so they are
    claimed by whichever thread is free (parallel.py; each block writes its own points'
    answers: no value depends on the thread). `threads`: numba.get_num_threads()."""
    n = rows.shape[0]
    cos_a = np.cos(half + margin)
    sin_a = np.sin(half + margin)
    seed, wide = _seed_rays(pixel, margin, half, q, r)
    blocks = (n + _BLOCK - 1) // _BLOCK
    claimed = counter()
    for _worker in prange(min(threads, blocks)):
        while True:
            b = claim(claimed)
            if b >= blocks:
                break
            _reached_block(b, points, rows, n, center, radius, axis, half, pixel, margin,
                           cos_a, sin_a, seed, wide, reach, seeds)


@njit(cache=True, inline="always", error_model="numpy")
def _reached_block(b, points, rows, n, center, radius, axis, half, pixel, margin, cos_a,
                   sin_a, seed, wide, reach, seeds):
    """Block b of _scan_reached."""
    k0 = b * _BLOCK
    count = min(n, k0 + _BLOCK) - k0
    s = np.empty((7, _BLOCK))  # as in _scan
    _load_block(points, rows, k0, count, s)
    # the block's ball: the mean of its points, the farthest of them from it
    b0 = b1 = b2 = 0.0
    for k in range(count):
        b0 += s[0, k]
        b1 += s[1, k]
        b2 += s[2, k]
    b0, b1, b2 = b0 / count, b1 / count, b2 / count
    rho = 0.0
    for k in range(count):
        rho = max(rho, math.sqrt((s[0, k] - b0) ** 2 + (s[1, k] - b1) ** 2
                                 + (s[2, k] - b2) ** 2))
    rho = rho * (1.0 + 1e-9) + 1e-12  # rounding to spare
    for j in range(center.shape[0]):
        if not wide[j] and _block_misses(b0, b1, b2, rho, center[j], radius[j] * 1.001,
                                          axis[j], cos_a[j], sin_a[j]):
            continue
        _scan_tile(s, count, j, center, radius, axis, half, margin, cos_a, sin_a, seed,
                   wide[j])
    for k in range(count):
        j_in = int(s[5, k])
        i = rows[k0 + k]
        reach[i] = j_in >= 0
        if j_in >= 0:
            seeds[i, 0] = pixel[j_in, 0]
            seeds[i, 1] = pixel[j_in, 1]


@njit(cache=True, inline="always", error_model="numpy")
def _block_misses(b0, b1, b2, rho, center, rad, axis, cos_a, sin_a):
    """True if no point within rho of B = (b0, b1, b2) passes a tile's test (ball (C, rad),
    its 1.001 included; cone of half-angle a below a right angle, cos_a and sin_a of it).
    With |B - C| > rad + rho, each such point P is |P - C| > rad from C, so it passes only
    if its angle from the axis is at most a + asin(rad / |P - C|) <= a + s1, s1 =
    asin(rad / (|B - C| - rho)); and P - C is within s2 = asin(rho / |B - C|) of B - C.
    So B - C is within a + s1 + s2 of the axis if any P passes. Tested as cosines, with
    1e-9 to spare; where a spread is wide (a sine of 1/2 or more, so that a + s1 + s2 could
    pass a half turn, where cosines no longer order angles) the tile is kept."""
    v0, v1, v2 = b0 - center[0], b1 - center[1], b2 - center[2]
    dist = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if not dist > rad + rho:
        return False
    x1 = rad / (dist - rho)
    x2 = rho / dist
    if not (x1 < 0.5 and x2 < 0.5):
        return False
    c1 = math.sqrt(1.0 - x1 * x1)
    c2 = math.sqrt(1.0 - x2 * x2)
    cos_s = c1 * c2 - x1 * x2  # cos(s1 + s2)
    sin_s = x1 * c2 + c1 * x2
    c = (v0 * axis[0] + v1 * axis[1] + v2 * axis[2]) / dist
    return c < cos_a * cos_s - sin_a * sin_s - 1e-9


@njit(cache=True, inline="always", error_model="numpy")
def _scan_tile(s, count, j, center, radius, axis, half, margin, cos_a, sin_a, seed, wide):
    """Tile j against a block's points (rows of `s`, see _scan), best answers updated."""
    cx, cy, cz = center[j, 0], center[j, 1], center[j, 2]
    qx, qy, qz = seed[j, 0], seed[j, 1], seed[j, 2]
    rx, ry, rz = seed[j, 3], seed[j, 4], seed[j, 5]
    ax, ay, az = axis[j, 0], axis[j, 1], axis[j, 2]
    rad = radius[j]
    ca, sa = cos_a[j], sin_a[j]
    a = half[j] + margin
    jf = float(j)
    if not wide:
        for k in range(count):
            v0 = s[0, k] - cx
            v1 = s[1, k] - cy
            v2 = s[2, k] - cz
            dist = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
            d0 = s[0, k] - qx
            d1 = s[1, k] - qy
            d2 = s[2, k] - qz
            inv = 1.0 / max(math.sqrt(d0 * d0 + d1 * d1 + d2 * d2), 1e-30)
            e = (d0 * inv - rx) ** 2 + (d1 * inv - ry) ** 2 + (d2 * inv - rz) ** 2
            better = e < s[4, k]
            s[4, k] = e if better else s[4, k]
            s[6, k] = jf if better else s[6, k]
            # angle <= half + margin + spread, as cosines (no trigonometry per test):
            # cos(a + s) = cos a cos s - sin a sin s with sin s = radius / dist
            sin_s = rad / dist
            c = (v0 * ax + v1 * ay + v2 * az) / dist
            bound = ca * math.sqrt(1.0 - sin_s * sin_s) - sa * sin_s
            inside = (dist <= rad * 1.001) | (sin_s >= 1.0) | (c >= bound)
            better = inside & (e < s[3, k])
            s[3, k] = e if better else s[3, k]
            s[5, k] = jf if better else s[5, k]
        return
    for k in range(count):  # a wide cone: as above, with the arcsine where it decides
        v0 = s[0, k] - cx
        v1 = s[1, k] - cy
        v2 = s[2, k] - cz
        dist = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        d0 = s[0, k] - qx
        d1 = s[1, k] - qy
        d2 = s[2, k] - qz
        inv = 1.0 / max(math.sqrt(d0 * d0 + d1 * d1 + d2 * d2), 1e-30)
        e = (d0 * inv - rx) ** 2 + (d1 * inv - ry) ** 2 + (d2 * inv - rz) ** 2
        if e < s[4, k]:
            s[4, k] = e
            s[6, k] = jf
        inside = dist <= rad * 1.001
        if not inside:
            sin_s = rad / dist
            if sin_s >= 1.0 or a + math.asin(sin_s) >= math.pi:
                inside = True
            else:
                c = (v0 * ax + v1 * ay + v2 * az) / dist
                bound = ca * math.sqrt(1.0 - sin_s * sin_s) - sa * sin_s
                inside = c >= bound
        if inside and e < s[3, k]:
            s[3, k] = e
            s[5, k] = jf


def scan_parts(parts: list[PartTiles], points: np.ndarray, q: np.ndarray, r: np.ndarray,
               polygons: np.ndarray, ws=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(reach (P, N), seeds (P, N, 2), todo (P, N)): row p is part p's
    scan_needed(points, q, r, polygons) (the parts of one reflector: q and r their ray
    grid, one margin), each pass one parallel region for all
    parts: the cull by each part's ball and cone (_candidates_parts), the tiles reaching
    each point (_scan_reached_parts), the polygon join (_join_parts), the seeds of the
    points needed but reached by none (_scan_parts). Each point's answers in each part
    are the part's alone: the same tests in the same order. `ws`: a RasterWorkspace to
    hold the arrays (valid until its next use), else fresh ones."""
    count = len(parts)
    n = points.shape[0]
    points = np.ascontiguousarray(points, np.float64)
    polygons = np.ascontiguousarray(polygons, np.int64)
    margin = parts[0].margin
    assert all(part.margin == margin for part in parts)
    # each part's ball and cone, with cos and sin of its angle as candidates() takes them
    ball = np.empty((count, 9))
    for p, part in enumerate(parts):
        a = part.part_half + part.margin
        ball[p, :3] = part.part_center
        ball[p, 3:6] = part.part_axis
        ball[p, 6:] = math.cos(a), math.sin(a), a
    radius = np.array([part.part_radius for part in parts])
    near = scratch(ws, "scan_near", (count, n), np.bool_)
    _candidates_parts(points, ball, radius, near)
    # the parts' tiles joined: part p's are rows tile_start[p] ..
    tile_start = np.zeros(count + 1, np.int64)
    tile_start[1:] = np.cumsum([len(part.radius) for part in parts])
    tiles = (np.concatenate([part.center for part in parts]),
             np.concatenate([part.radius for part in parts]),
             np.concatenate([part.axis for part in parts]),
             np.concatenate([part.half for part in parts]),
             np.concatenate([part.pixel for part in parts]))
    reach = scratch(ws, "scan_reach", (count, n), np.bool_)
    reach.fill(False)
    seeds = scratch(ws, "scan_seeds", (count, n, 2), np.float64)
    seeds.fill(np.nan)
    rows, row_start, block_start = rows_of(near)
    _scan_reached_parts(points, rows, row_start, block_start, tile_start, *tiles, margin, q,
                        r, reach, seeds, numba.get_num_threads())
    todo = scratch(ws, "scan_todo", (count, n), np.bool_)
    todo[:] = reach
    _join_parts(reach, polygons, todo)
    rows, row_start, block_start = rows_of(todo & ~reach)
    if rows.size:
        _scan_parts(points, rows, row_start, block_start, tile_start, *tiles, margin, q, r,
                    reach, seeds)
    return reach, seeds, todo


def rows_of(marks: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rows: the marked points of each part (P, N) joined, ascending within a part,
    row_start (P + 1,): part p's rows, block_start (P + 1,): the first _BLOCK of part p's
    rows). One kernel (a flatnonzero a part was 14 numpy calls, three times a mask
    frame)."""
    marks = np.ascontiguousarray(marks, np.bool_)
    row_start = np.zeros(marks.shape[0] + 1, np.int64)
    block_start = np.zeros(marks.shape[0] + 1, np.int64)
    rows = _rows_of(marks, row_start, block_start)
    return rows, row_start, block_start


@njit(cache=True)
def _rows_of(marks, row_start, block_start):
    """rows_of's rows, with row_start and block_start filled."""
    parts, n = marks.shape
    for p in range(parts):
        count = 0
        for k in range(n):
            count += marks[p, k]
        row_start[p + 1] = row_start[p] + count
        block_start[p + 1] = block_start[p] + (count + _BLOCK - 1) // _BLOCK
    rows = np.empty(row_start[parts], np.int64)
    i = 0
    for p in range(parts):
        for k in range(n):
            if marks[p, k]:
                rows[i] = k
                i += 1
    return rows


@njit(cache=True, parallel=True, error_model="numpy")
def _candidates_parts(points, ball, radius, out):
    """_candidates for several parts at once: out[p] (N,) the points part p's ball and cone
    may reach (ball[p]: center, axis, cos a, sin a, a; radius[p]); one region, the parts'
    blocks of points handed out in turn."""
    n = points.shape[0]
    blocks = (n + 1023) // 1024
    for item in prange(ball.shape[0] * blocks):
        p = item // blocks
        k0 = (item % blocks) * 1024
        for k in range(k0, min(n, k0 + 1024)):
            out[p, k] = _candidate(points, k, ball[p, :3], radius[p], ball[p, 3:6],
                                   ball[p, 6], ball[p, 7], ball[p, 8])


@njit(cache=True, parallel=True)
def _join_parts(flag, polygons, out):
    """joined for several parts at once: out[p] = flag[p] and every point of a polygon one
    of whose points has it (out starts as a copy of flag)."""
    for p in prange(flag.shape[0]):
        _join(flag[p], polygons, out[p])


@njit(cache=True, inline="always")
def _part_of_block(block_start, b):
    """The part whose blocks hold block b (block_start: each part's first)."""
    p = 0
    while block_start[p + 1] <= b:
        p += 1
    return p


@njit(cache=True)
def _tile_rays(pixel, half, margin, q, r):
    """(cos, sin of each tile's half-angle with the margin, its seed ray, its wide flag)
    as _scan and _scan_reached make them (math.cos and np.cos of an array take the same
    libm call), in one thread: no parallel loop of their own."""
    tiles = pixel.shape[0]
    cos_a = np.empty(tiles)
    sin_a = np.empty(tiles)
    for j in range(tiles):
        cos_a[j] = math.cos(half[j] + margin)
        sin_a[j] = math.sin(half[j] + margin)
    seed, wide = _seed_rays(pixel, margin, half, q, r)
    return cos_a, sin_a, seed, wide


@njit(cache=True, parallel=True, error_model="numpy")
def _scan_reached_parts(points, rows, row_start, block_start, tile_start, center, radius,
                        axis, half, pixel, margin, q, r, reach, seeds, threads):
    """_scan_reached for several parts at once: part p's points rows[row_start[p]:
    row_start[p + 1]], its tiles rows tile_start[p] .. of the joined tile arrays, its
    answers into reach[p] and seeds[p]; its blocks (block_start[p] ..) claimed with every
    other part's by whichever thread is free. Each block is the block of _scan_reached on
    the part alone."""
    cos_a, sin_a, seed, wide = _tile_rays(pixel, half, margin, q, r)
    blocks = block_start[-1]
    claimed = counter()
    for _worker in prange(min(threads, blocks)):
        while True:
            b = claim(claimed)
            if b >= blocks:
                break
            p = _part_of_block(block_start, b)
            r0, r1 = row_start[p], row_start[p + 1]
            t0, t1 = tile_start[p], tile_start[p + 1]
            _reached_block(b - block_start[p], points, rows[r0:r1], r1 - r0, center[t0:t1],
                           radius[t0:t1], axis[t0:t1], half[t0:t1], pixel[t0:t1], margin,
                           cos_a[t0:t1], sin_a[t0:t1], seed[t0:t1], wide[t0:t1], reach[p],
                           seeds[p])


@njit(cache=True, parallel=True, error_model="numpy")
def _scan_parts(points, rows, row_start, block_start, tile_start, center, radius, axis, half,
                pixel, margin, q, r, reach, seeds):
    """_scan for several parts at once (as _scan_reached_parts lays them out), blocks in
    one parallel loop."""
    cos_a, sin_a, seed, wide = _tile_rays(pixel, half, margin, q, r)
    for b in prange(block_start[-1]):
        p = _part_of_block(block_start, b)
        r0, r1 = row_start[p], row_start[p + 1]
        t0, t1 = tile_start[p], tile_start[p + 1]
        _scan_block(b - block_start[p], points, rows[r0:r1], r1 - r0, center[t0:t1],
                    radius[t0:t1], axis[t0:t1], half[t0:t1], pixel[t0:t1], margin,
                    cos_a[t0:t1], sin_a[t0:t1], seed[t0:t1], wide[t0:t1], reach[p], seeds[p])
