"""Camera model: look-at, OpenGL perspective, pixel rays, and camera paths.

Spaces: world (right-handed, y up) -> eye (camera at origin, looking down -z, y up) ->
clip (4D, OpenGL projection) -> NDC ([-1, 1]^3) -> screen (pixels, x right, y down,
pixel (i, j) covers [i, i+1) x [j, j+1) with its center at (i + 0.5, j + 0.5)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from .config.camera import CameraConfig


def normalize(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


@dataclass(frozen=True)
class Camera:
    eye: np.ndarray  # world
    target: np.ndarray  # world
    up: np.ndarray  # world, need not be orthogonal to the view direction
    fov_y: float  # full vertical angle, degrees
    width: int
    height: int
    near: float
    far: float

    @property
    def aspect(self) -> float:
        return self.width / self.height

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World-space right, up and backward (+z of eye space) unit vectors."""
        back = normalize(self.eye - self.target)
        right = normalize(np.cross(self.up, back))
        up = np.cross(back, right)
        return right, up, back

    def view_matrix(self) -> np.ndarray:
        """World -> eye (4x4)."""
        right, up, back = self.basis()
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = right, up, back
        m[:3, 3] = -m[:3, :3] @ self.eye
        return m

    def projection_matrix(self) -> np.ndarray:
        """Eye -> clip, OpenGL convention: near plane to NDC z = -1, far to +1."""
        f = 1.0 / math.tan(math.radians(self.fov_y) / 2.0)
        n, fa = self.near, self.far
        p = np.zeros((4, 4))
        p[0, 0] = f / self.aspect
        p[1, 1] = f
        p[2, 2] = (fa + n) / (n - fa)
        p[2, 3] = 2.0 * fa * n / (n - fa)
        p[3, 2] = -1.0
        return p

    def pixel_directions(self, samples: int = 1) -> np.ndarray:
        """World-space ray directions (H, W, s*s, 3) through a regular s x s grid in each pixel.

        Not normalised: each has eye-space z = -1, so the ray parameter t of a hit is its
        eye-space depth (the Z channel). With s = 1 the ray passes the pixel center.
        """
        t = math.tan(math.radians(self.fov_y) / 2.0)
        offsets = (np.arange(samples) + 0.5) / samples
        sx = (np.arange(self.width)[:, None] + offsets[None, :]).reshape(-1)  # screen x
        sy = (np.arange(self.height)[:, None] + offsets[None, :]).reshape(-1)  # screen y
        x_ndc = 2.0 * sx / self.width - 1.0
        y_ndc = 1.0 - 2.0 * sy / self.height
        xe = (x_ndc * t * self.aspect).reshape(self.width, samples)
        ye = (y_ndc * t).reshape(self.height, samples)
        right, up, back = self.basis()
        # (H, s_y, W, s_x) -> (H, W, s_y*s_x)
        d = (
            xe[None, None, :, :, None] * right
            + ye[:, :, None, None, None] * up
            - back[None, None, None, None, :]
        )
        d = d.transpose(0, 2, 1, 3, 4).reshape(self.height, self.width, samples * samples, 3)
        return d


def primary_rays(camera: Camera, samples: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """float32 (origins, directions), (H * W * s * s, 3): the rays of `pixel_directions`
    (same order, eye-space z = -1 per direction), starting on the near plane."""
    right, up, back = camera.basis()
    n = camera.height * camera.width * samples * samples
    origins = np.empty((n, 3), np.float32)
    dirs = np.empty((n, 3), np.float32)
    _primary_rays(np.asarray(camera.eye, np.float64), right, up, back,
                  math.tan(math.radians(camera.fov_y) / 2.0), camera.width, camera.height,
                  samples, camera.near, origins, dirs)
    return origins, dirs


@njit(cache=True, parallel=True)
def _primary_rays(eye, right, up, back, tan_half, width, height, samples, near, origins, dirs):
    aspect = width / height
    per_row = width * samples * samples
    for j in prange(height):
        for i in range(width):
            for sy in range(samples):
                y_ndc = 1.0 - 2.0 * (j + (sy + 0.5) / samples) / height
                ye = y_ndc * tan_half
                for sx in range(samples):
                    x_ndc = 2.0 * (i + (sx + 0.5) / samples) / width - 1.0
                    xe = x_ndc * tan_half * aspect
                    k = j * per_row + (i * samples + sy) * samples + sx
                    for a in range(3):
                        d = xe * right[a] + ye * up[a] - back[a]
                        dirs[k, a] = d
                        origins[k, a] = eye[a] + near * d


def camera_from_config(cfg: CameraConfig, frame: int = 0) -> Camera:
    """The camera of frame `frame` (0-based), interpolating the path's keys if there is one."""
    eye, target = np.array(cfg.eye, float), np.array(cfg.target, float)
    up, fov = np.array(cfg.up, float), cfg.fov_y
    if cfg.path is not None:
        keys = cfg.path.keys
        n = cfg.path.frames
        s = 0.0 if n == 1 else frame / (n - 1) * (len(keys) - 1)
        eyes = np.array([k.eye for k in keys], float)
        targets = np.array([k.target for k in keys], float)
        ups = np.array([k.up if k.up is not None else cfg.up for k in keys], float)
        fovs = np.array([[k.fov_y if k.fov_y is not None else cfg.fov_y] for k in keys], float)
        interp = catmull_rom if cfg.path.interpolation == "catmull-rom" else linear
        eye, target, up = interp(eyes, s), interp(targets, s), interp(ups, s)
        fov = float(interp(fovs, s)[0])
    return Camera(eye, target, up, fov, cfg.width, cfg.height, cfg.near, cfg.far)


def linear(points: np.ndarray, s: float) -> np.ndarray:
    """Piecewise-linear interpolation of keys at parameter s in [0, len-1]."""
    i = min(int(math.floor(s)), len(points) - 2) if len(points) > 1 else 0
    if len(points) == 1:
        return points[0]
    u = s - i
    return (1 - u) * points[i] + u * points[i + 1]


def catmull_rom(points: np.ndarray, s: float) -> np.ndarray:
    """Uniform Catmull-Rom through the keys (end keys repeated); passes through every key."""
    if len(points) == 1:
        return points[0]
    i = min(int(math.floor(s)), len(points) - 2)
    u = s - i
    p0 = points[max(i - 1, 0)]
    p1, p2 = points[i], points[i + 1]
    p3 = points[min(i + 2, len(points) - 1)]
    return 0.5 * (
        2 * p1
        + (-p0 + p2) * u
        + (2 * p0 - 5 * p1 + 4 * p2 - p3) * u * u
        + (-p0 + 3 * p1 - 3 * p2 + p3) * u * u * u
    )
