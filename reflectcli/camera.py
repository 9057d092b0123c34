"""Camera model: look-at, OpenGL perspective, pixel rays, and camera paths.

Spaces: world (right-handed, y up) -> eye (camera at origin, looking down -z, y up) ->
clip (4D, OpenGL projection) -> NDC ([-1, 1]^3) -> screen (pixels, x right, y down,
pixel (i, j) covers [i, i+1) x [j, j+1) with its center at (i + 0.5, j + 0.5)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .config.camera import CameraConfig
from .geometry import far_plane_clip, oblique_projection, transform_plane


def normalize(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b of two 3-vectors: np.cross's products and differences, in its order (the same
    bits), without its axis handling (two crosses made `basis` 120 us, most of the cost of
    a frame's clip_from_world)."""
    a0, a1, a2 = (float(v) for v in a)
    b0, b1, b2 = (float(v) for v in b)
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def screen_from_ndc(x_ndc: float, y_ndc: float, width: int, height: int) -> tuple[float, float]:
    """NDC ([-1, 1], y up) -> screen (pixels, y down): the one place this mapping is written.
    Kernels compile this very function (`njit(inline="always")(screen_from_ndc)`)."""
    return (x_ndc + 1.0) * 0.5 * width, (1.0 - y_ndc) * 0.5 * height


_CLIP_FROM_WORLD: dict[tuple, np.ndarray] = {}  # Camera.clip_from_world's, by the camera's values


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
        right = normalize(_cross(self.up, back))
        up = _cross(back, right)
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

    def clip_from_world(self) -> np.ndarray:
        """World -> clip (4x4): the view-projection product, written here once. A new
        array each call; made once per camera (by its values: a scene hands a new Camera
        each frame) and copied after (making it took 50-150 us between a frame's kernels)."""
        key = tuple((a.dtype.str, a.shape, a.tobytes())
                    for a in map(np.asarray, (self.eye, self.target, self.up))) + (
            type(self), self.fov_y, self.width, self.height, self.near, self.far)
        made = _CLIP_FROM_WORLD.get(key)
        if made is None:
            if len(_CLIP_FROM_WORLD) >= 64:  # an animated camera: keep the latest few
                _CLIP_FROM_WORLD.clear()
            made = _CLIP_FROM_WORLD[key] = self.projection_matrix() @ self.view_matrix()
        return made.copy()

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


def camera_from_config(cfg: CameraConfig, frame_index: int = 0) -> Camera:
    """The camera of frame `frame_index` (0-based), interpolating the path's keys if any."""
    eye, target = np.array(cfg.eye, float), np.array(cfg.target, float)
    up, fov = np.array(cfg.up, float), cfg.fov_y
    if cfg.path is not None:
        keys = cfg.path.keys
        n = cfg.path.frames
        s = 0.0 if n == 1 else frame_index / (n - 1) * (len(keys) - 1)
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


def standard_planes() -> np.ndarray:
    """Clip-space planes (a, b, c, e): keep a*x + b*y + c*z + e*w >= 0. Near, then far."""
    return np.array([[0.0, 0.0, 1.0, 1.0], [0.0, 0.0, -1.0, 1.0]])


def reflection_pass_matrices(
    camera: Camera, chain: np.ndarray, plane: np.ndarray, clip: str
) -> tuple[np.ndarray, np.ndarray]:
    """(world -> clip matrix, clip-space planes) of one reflection pass.

    `chain` is the product of reflection matrices (world -> virtual world), `plane` (4,) the
    mirror plane in world space oriented so that kept points (in front of the mirror, seen
    from the previous level's eye) are >= 0.
    """
    view = camera.view_matrix() @ chain
    proj = camera.projection_matrix()
    if clip == "oblique":
        proj = oblique_projection(proj, transform_plane(plane, view))
        # near plane = mirror plane; clip far against the original far plane, not the tilted one
        planes = np.array([[0.0, 0.0, 1.0, 1.0], far_plane_clip(proj, camera.far)])
        return proj @ view, planes
    clip_from_world = proj @ view
    if clip == "plane":
        extra = transform_plane(plane, clip_from_world)
        return clip_from_world, np.vstack([standard_planes(), extra / np.abs(extra).max()])
    return clip_from_world, standard_planes()
