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
        rows_of_rays(j, j + 1, 0, cam, origins, dirs)


@njit(cache=True, inline="always")
def rows_of_rays(j0, j1, shift, cam, origins, dirs):
    """The rays of image rows j0 .. j1 - 1 into origins and dirs (row-major, samples of a
    pixel together), ray k of the frame at row k - shift. `cam`: camera_rays. The per-row
    (ye) and per-sample-column (xe) factors, and their products with the basis, are worked
    out once each by the same expressions as per ray (same values, bit for bit); directions
    and origins are worked in float64 and stored as float32."""
    eye, right, up, back, tan_half, width, height, samples, near = cam
    aspect = width / height
    per_row = width * samples * samples
    # xe * right[a] for every sample column (i, sx), ye * up[a] for every sample row
    x_right = np.empty((width * samples, 3))
    for i in range(width):
        for sx in range(samples):
            x_ndc = 2.0 * (i + (sx + 0.5) / samples) / width - 1.0
            xe = x_ndc * tan_half * aspect
            for a in range(3):
                x_right[i * samples + sx, a] = xe * right[a]
    y_up = np.empty((samples, 3))
    ex, ey, ez = eye[0], eye[1], eye[2]
    bx, by, bz = back[0], back[1], back[2]
    for j in range(j0, j1):
        for sy in range(samples):
            ye = (1.0 - 2.0 * (j + (sy + 0.5) / samples) / height) * tan_half
            for a in range(3):
                y_up[sy, a] = ye * up[a]
        if samples == 1:
            _row(j * per_row - shift, width, x_right, y_up[0, 0], y_up[0, 1], y_up[0, 2], bx,
                 by, bz, ex, ey, ez, near, origins, dirs)
            continue
        for i in range(width):
            for sy in range(samples):
                for sx in range(samples):
                    k = j * per_row + (i * samples + sy) * samples + sx - shift
                    c = i * samples + sx
                    for a in range(3):
                        d = x_right[c, a] + y_up[sy, a] - back[a]
                        dirs[k, a] = d
                        origins[k, a] = eye[a] + near * d


@njit(cache=True, inline="always")
def _row(first, width, x_right, yx, yy, yz, bx, by, bz, ex, ey, ez, near, origins, dirs):
    """One sample per pixel: the rays of one row, from ray `first` on, in a loop with no
    inner loops (it vectorises). Indices unsigned, as in resolve.resolve_range."""
    for n in range(width):
        i = np.uint64(n)
        k = np.uint64(first + n)
        dx = x_right[i, 0] + yx - bx
        dy = x_right[i, 1] + yy - by
        dz = x_right[i, 2] + yz - bz
        dirs[k, 0] = dx
        dirs[k, 1] = dy
        dirs[k, 2] = dz
        origins[k, 0] = ex + near * dx
        origins[k, 1] = ey + near * dy
        origins[k, 2] = ez + near * dz
