"""Primary rays: one per pixel sample, from the camera's near plane (a numba kernel)."""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

from ..camera import Camera


def primary_rays(camera: Camera, samples: int = 1, out: tuple[np.ndarray, np.ndarray] | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """float32 (origins, directions), (H * W * s * s, 3): the rays of `pixel_directions`
    (same order, eye-space z = -1 per direction), starting on the near plane. `out`: two
    (n, 3) float32 arrays to fill (kept across frames by the tracer) instead of new ones."""
    right, up, back = camera.basis()
    n = camera.height * camera.width * samples * samples
    if out is None:
        origins = np.empty((n, 3), np.float32)
        dirs = np.empty((n, 3), np.float32)
    else:
        origins, dirs = out
    with numba.parallel_chunksize(8):  # rows, not rays (the tracer's chunk size is for rays)
        _primary_rays(np.asarray(camera.eye, np.float64), right, up, back,
                      math.tan(math.radians(camera.fov_y) / 2.0), camera.width, camera.height,
                      samples, camera.near, origins, dirs)
    return origins, dirs


@njit(cache=True, parallel=True)
def _primary_rays(eye, right, up, back, tan_half, width, height, samples, near, origins, dirs):
    """One row of pixels per work item. The per-row (ye) and per-sample-column (xe) factors
    are worked out once each, by the same expressions as per ray (same values, bit for bit)."""
    aspect = width / height
    per_row = width * samples * samples
    for j in prange(height):
        ye = np.empty(samples)
        for sy in range(samples):
            ye[sy] = (1.0 - 2.0 * (j + (sy + 0.5) / samples) / height) * tan_half
        for i in range(width):
            for sy in range(samples):
                for sx in range(samples):
                    x_ndc = 2.0 * (i + (sx + 0.5) / samples) / width - 1.0
                    xe = x_ndc * tan_half * aspect
                    k = j * per_row + (i * samples + sy) * samples + sx
                    for a in range(3):
                        d = xe * right[a] + ye[sy] * up[a] - back[a]
                        dirs[k, a] = d
                        origins[k, a] = eye[a] + near * d
