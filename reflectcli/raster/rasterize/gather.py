"""Triangles given as indices into shared points, gathered into the rasterizer's corner
and flag arrays one triangle at a time, by the thread that draws it (`rasterize_passes`
with `gather`; virtual's passes draw their virtual triangles so, with no pass of their own
over the triangles)."""

import numpy as np
from numba import njit

from .constants import FLAG_MIRROR, FLAG_SKIP


@njit(cache=True, inline="always")
def gather_triangle(points, hidden, corner_index, surface, n_objects, corners, flags, t):
    """corners[t, i] = points[corner_index[t, i]] in float32 (what the rasterizer takes),
    and flags[t]: FLAG_MIRROR for a mirror's triangle (surface[t] >= n_objects), FLAG_SKIP
    where all three of its points are `hidden` (virtual: the paper drops polygons wholly in
    the hidden region)."""
    every = True
    for i in range(3):
        q = corner_index[t, i]
        every &= hidden[q]
        for c in range(3):
            corners[t, i, c] = np.float32(points[q, c])
    flags[t] = (FLAG_MIRROR if surface[t] >= n_objects else 0) | (FLAG_SKIP if every else 0)
