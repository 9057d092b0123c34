"""The order the warp visits a map's zexels in, as runs (row, first column, stop, step)."""

from __future__ import annotations

import math

import numpy as np


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
