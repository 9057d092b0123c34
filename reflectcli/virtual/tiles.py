"""Tile culling for the screen-space refinement: a reflector part's pixels in square tiles,
each bounding where its reflected rays go, so that points no ray of the part can reach are
skipped and the others get a seed pixel near their reflection."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


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
                 margin_degrees: float = 1.0) -> None:
        h, w = inside.shape
        ys, xs = np.nonzero(inside)
        tiles = np.unique((ys // size) * (w // size + 1) + xs // size)
        n = tiles.size
        self.center = np.empty((n, 3))
        self.radius = np.empty(n)
        self.axis = np.empty((n, 3))
        self.half = np.empty(n)
        self.pixel = np.empty((n, 2))
        for j, t in enumerate(tiles):
            ty, tx = divmod(int(t), w // size + 1)
            y0, x0 = ty * size, tx * size
            ey, ex = max(y0 - 1, 0), max(x0 - 1, 0)  # grown up and left by a pixel
            block = inside[ey:y0 + size, ex:x0 + size]
            by, bx = np.nonzero(block)
            pts = q[by + ey, bx + ex]
            dirs = r[by + ey, bx + ex]
            c = pts.mean(axis=0)
            a = dirs.sum(axis=0)
            a /= max(float(np.linalg.norm(a)), 1e-30)
            self.center[j] = c
            self.radius[j] = np.linalg.norm(pts - c, axis=1).max()
            self.axis[j] = a
            self.half[j] = np.arccos(np.clip(dirs @ a, -1.0, 1.0)).max()
            own = (by + ey >= y0) & (bx + ex >= x0)  # the seed: the tile's own middle pixel
            mid = np.flatnonzero(own)[np.argmin(np.linalg.norm(pts[own] - c, axis=1))]
            self.pixel[j] = bx[mid] + ex + 0.5, by[mid] + ey + 0.5
        self.margin = math.radians(margin_degrees)
        # one ball and cone holding every tile's (with their margins): a point outside the
        # part's cone is outside every tile's (see candidates)
        self.part_center = self.center.mean(axis=0) if n else np.zeros(3)
        self.part_radius = (float(np.max(np.linalg.norm(self.center - self.part_center, axis=1)
                                         + self.radius * 1.001)) * (1 + 1e-9) if n else 0.0)
        a = self.axis.sum(axis=0) if n else np.zeros(3)
        norm = float(np.linalg.norm(a))
        self.part_axis = a / norm if norm > 0 else np.array([0.0, 0.0, 1.0])
        self.part_half = (float(np.max(np.arccos(np.clip(self.axis @ self.part_axis, -1, 1))
                                       + self.half)) + 1e-9 if n and norm > 0 else math.pi)

    def candidates(self, points: np.ndarray) -> np.ndarray:
        """(N,) bool: points the part's ball and cone may reach; the others are reached by
        no tile. A tile's test holds exactly the points some ray from its ball along a
        direction of its cone passes (or its ball, grown by 0.1%); each such ray starts in the
        part's ball along a direction of the part's cone, so the same test with the part's
        ball and cone holds the point too (with 1e-9 to spare for rounding)."""
        v = np.asarray(points, np.float64) - self.part_center
        dist = np.linalg.norm(v, axis=1)
        a = self.part_half + self.margin
        with np.errstate(divide="ignore", invalid="ignore"):
            sin_s = np.minimum(self.part_radius / dist, 1.0)
            c = (v @ self.part_axis) / dist
            bound = math.cos(a) * np.sqrt(1.0 - sin_s * sin_s) - math.sin(a) * sin_s
            wide = a + np.arcsin(sin_s) >= math.pi if a >= 0.5 * math.pi else False
        return ~(c < bound - 1e-9) | (dist <= self.part_radius) | (sin_s >= 1.0) | wide

    def scan(self, points: np.ndarray, q: np.ndarray, r: np.ndarray,
             polygons: np.ndarray | None = None):
        """(reach (N,) bool: some tile's cone holds the point; seeds (N, 2): the middle pixel
        of the tile whose ray passes closest to it, among the tiles that reach it, else
        among all). With `polygons` (T, 3) point indices, seeds are found only for the
        points a part needs: those that reach it and those a polygon joins to one that does
        (NaN elsewhere); points outside the part's own cone skip the per-tile tests."""
        n = points.shape[0]
        points = np.ascontiguousarray(points, np.float64)
        reach = np.zeros(n, np.bool_)
        seeds = np.full((n, 2), np.nan)
        if polygons is None:
            self._scan_rows(points, q, r, np.arange(n), reach, seeds)
            return reach, seeds
        near = self.candidates(points)
        self._scan_rows(points, q, r, np.flatnonzero(near), reach, seeds)
        todo = reach.copy()
        todo[polygons[reach[polygons].any(axis=1)].ravel()] = True
        self._scan_rows(points, q, r, np.flatnonzero(todo & ~near), reach, seeds)
        return reach, seeds

    def _scan_rows(self, points, q, r, rows, reach, seeds) -> None:
        """_scan of points[rows] into reach[rows] and seeds[rows] (each point's answer is its
        own: a subset gives the same answers)."""
        if rows.size == 0:
            return
        sub_reach = np.zeros(rows.size, np.bool_)
        sub_seeds = np.full((rows.size, 2), np.nan)
        _scan(np.ascontiguousarray(points[rows]), self.center, self.radius, self.axis,
              self.half, self.pixel, self.margin, q, r, sub_reach, sub_seeds)
        reach[rows] = sub_reach
        seeds[rows] = sub_seeds


@njit(cache=True, parallel=True)
def _scan(points, center, radius, axis, half, pixel, margin, q, r, reach, seeds):
    cos_a = np.cos(half + margin)
    sin_a = np.sin(half + margin)
    for k in prange(points.shape[0]):
        p = points[k]
        best_in = np.inf
        best_any = np.inf
        j_in = -1
        j_any = -1
        for j in range(center.shape[0]):
            v0 = p[0] - center[j, 0]
            v1 = p[1] - center[j, 1]
            v2 = p[2] - center[j, 2]
            dist = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
            x = int(pixel[j, 0])
            y = int(pixel[j, 1])
            d0 = p[0] - q[y, x, 0]
            d1 = p[1] - q[y, x, 1]
            d2 = p[2] - q[y, x, 2]
            inv = 1.0 / max(math.sqrt(d0 * d0 + d1 * d1 + d2 * d2), 1e-30)
            e = ((d0 * inv - r[y, x, 0]) ** 2 + (d1 * inv - r[y, x, 1]) ** 2
                 + (d2 * inv - r[y, x, 2]) ** 2)
            if e < best_any:
                best_any = e
                j_any = j
            inside = dist <= radius[j] * 1.001
            if not inside:
                # angle <= half + margin + spread, as cosines (no trigonometry per test):
                # cos(a + s) = cos a cos s - sin a sin s with sin s = radius / dist
                a = half[j] + margin
                sin_s = radius[j] / dist
                if sin_s >= 1.0 or (a >= 0.5 * math.pi and a + math.asin(sin_s) >= math.pi):
                    inside = True
                else:
                    c = (v0 * axis[j, 0] + v1 * axis[j, 1] + v2 * axis[j, 2]) / dist
                    bound = (cos_a[j] * math.sqrt(1.0 - sin_s * sin_s) - sin_a[j] * sin_s)
                    inside = c >= bound
            if inside and e < best_in:
                best_in = e
                j_in = j
        reach[k] = j_in >= 0
        j = j_in if j_in >= 0 else j_any
        if j >= 0:
            seeds[k, 0] = pixel[j, 0]
            seeds[k, 1] = pixel[j, 1]
