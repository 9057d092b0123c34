"""Primary rays: one per pixel sample, from the camera's near plane (numba kernels)."""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

from ..camera import Camera


def camera_rays(camera: Camera, samples: int) -> tuple:
    """The arguments of `rows_of_rays` after the row range: (eye, right, up, back, tan_half,
    width, height, samples, near), the camera's world-space basis in float64."""
    right, up, back = camera.basis()
    return (np.asarray(camera.eye, np.float64), right, up, back,
            math.tan(math.radians(camera.fov_y) / 2.0), camera.width, camera.height, samples,
            camera.near)


def primary_rays(camera: Camera, samples: int = 1, out: tuple[np.ndarray, np.ndarray] | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """float32 (origins, directions), (H * W * s * s, 3): the rays of `pixel_directions`
    (same order, eye-space z = -1 per direction), starting on the near plane. `out`: two
    (n, 3) float32 arrays to fill instead of new ones."""
    n = camera.height * camera.width * samples * samples
    if out is None:
        origins = np.empty((n, 3), np.float32)
        dirs = np.empty((n, 3), np.float32)
    else:
        origins, dirs = out
    with numba.parallel_chunksize(8):  # rows, not rays
        _primary_rays(camera_rays(camera, samples), origins, dirs)
    return origins, dirs


@njit(cache=True, parallel=True)
def _primary_rays(cam, origins, dirs):
    """One row of pixels per work item (`rows_of_rays`)."""
    height = cam[6]
    for j in prange(height):
        rows_of_rays(j, j + 1, cam, origins, dirs)


@njit(cache=True, inline="always")
def rows_of_rays(j0, j1, cam, origins, dirs):
    """The rays of image rows j0 .. j1 - 1 into origins and dirs (row-major, samples of a
    pixel together). `cam`: camera_rays. The per-row (ye) and per-sample-column (xe) factors
    are worked out once each, by the same expressions as per ray (same values, bit for bit);
    directions and origins are worked in float64 and stored as float32."""
    eye, right, up, back, tan_half, width, height, samples, near = cam
    aspect = width / height
    per_row = width * samples * samples
    ye = np.empty(samples)
    for j in range(j0, j1):
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
