"""Cube maps: six 90-degree rasterized views from a capture point, and their lookup.

Faces, in order: +x, -x, +y, -y, +z, -z. Each face is an ordinary camera image (row 0 at the
top, pixel centers at +0.5) from the capture point looking along the face axis with the up
vector of FACE_UP; the lookup of a world direction r picks the face of r's major axis and
projects r with that same camera, so texel centers round-trip exactly.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..camera import Camera
from ..raster.rasterize import FLAG_SKIP, rasterize, screen_from_ndc
from ..raster.shade import shade_buffers
from ..scene.types import Scene, Triangles

FACE_NAMES = ("+x", "-x", "+y", "-y", "+z", "-z")
FACE_AXES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
FACE_UP = np.array([[0, 1, 0], [0, 1, 0], [0, 0, 1], [0, 0, -1], [0, 1, 0], [0, 1, 0]], float)


def face_camera(face: int, point: np.ndarray, resolution: int, near: float, far: float) -> Camera:
    point = np.asarray(point, float)
    return Camera(point, point + FACE_AXES[face], FACE_UP[face], 90.0, resolution, resolution,
                  near, far)


def face_bases(point=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(6, 3, 3): per face the world-space right, up and forward unit vectors."""
    out = np.empty((6, 3, 3))
    for f in range(6):
        right, up, back = face_camera(f, np.asarray(point, float), 1, 0.1, 1.0).basis()
        out[f] = (right, up, -back)
    return out


def capture_cube(
    scene: Scene, tris: Triangles, flags: np.ndarray, point: np.ndarray, resolution: int,
    exclude_surface: int, near: float, far: float, which=range(6), out: np.ndarray | None = None,
) -> np.ndarray:
    """(6, R, R, 3) float32 linear colors seen from `point`, without surface `exclude_surface`
    (the reflector itself). Mirrors in view show (1 - r) * base: maps hold no reflections.
    Only the faces in `which` are captured; with `out` the others keep their contents
    (time-sliced updates), else they stay uninitialized."""
    faces = np.empty((6, resolution, resolution, 3), np.float32) if out is None else out
    pass_flags = flags | np.where(tris.surface == exclude_surface, FLAG_SKIP, 0).astype(np.uint8)
    for f in which:
        cam = face_camera(f, point, resolution, near, far)
        buffers = rasterize(tris.corners, pass_flags, cam.clip_from_world(),
                            resolution, resolution)
        faces[f], _ = shade_buffers(buffers, tris, scene, cam.eye)
    return faces


def lookup_cube(faces: np.ndarray, directions: np.ndarray, bilinear: bool) -> np.ndarray:
    """Colors (N, 3) of world directions (N, 3) in a cube map (6, R, R, 3)."""
    out = np.empty((directions.shape[0], 3), np.float32)
    bases = face_bases()
    for i in range(directions.shape[0]):
        out[i] = cube_sample(faces, bases, directions[i, 0], directions[i, 1], directions[i, 2],
                             bilinear)
    return out


@njit(cache=True)
def cube_face_coords(bases, rx, ry, rz):
    """(face, sx, sy): the face of r's major axis and r's screen position on it (pixels / R)."""
    ax, ay, az = abs(rx), abs(ry), abs(rz)
    if ax >= ay and ax >= az:
        face = 0 if rx > 0 else 1
    elif ay >= az:
        face = 2 if ry > 0 else 3
    else:
        face = 4 if rz > 0 else 5
    fwd = rx * bases[face, 2, 0] + ry * bases[face, 2, 1] + rz * bases[face, 2, 2]
    x_ndc = (rx * bases[face, 0, 0] + ry * bases[face, 0, 1] + rz * bases[face, 0, 2]) / fwd
    y_ndc = (rx * bases[face, 1, 0] + ry * bases[face, 1, 1] + rz * bases[face, 1, 2]) / fwd
    sx, sy = screen_from_ndc(x_ndc, y_ndc, 1, 1)  # a face 1 pixel wide
    return face, sx, sy


@njit(cache=True)
def cube_sample(faces, bases, rx, ry, rz, bilinear):
    """Nearest or bilinear (clamped at the face's edges) color of direction r."""
    face, u, v = cube_face_coords(bases, rx, ry, rz)
    return image_sample(faces[face], u, v, bilinear)


@njit(cache=True)
def image_sample(image, u, v, bilinear):
    """Color (r, g, b) as float32 at (u, v) in [0, 1]^2 of an (R, R, 3) image (row 0 at the
    top, v down), nearest or bilinear with the edges clamped. A tuple, not an array: a lookup
    a pixel allocated one (an envmap frame's lookups spent a third of their time so)."""
    res = image.shape[0]
    fx = u * res
    fy = v * res
    if not bilinear or res == 1:
        x = min(max(int(fx), 0), res - 1)
        y = min(max(int(fy), 0), res - 1)
        return (np.float32(image[y, x, 0]), np.float32(image[y, x, 1]),
                np.float32(image[y, x, 2]))
    fx = min(max(fx - 0.5, 0.0), res - 1.0)
    fy = min(max(fy - 0.5, 0.0), res - 1.0)
    x0 = min(int(fx), res - 2)
    y0 = min(int(fy), res - 2)
    ax = fx - x0
    ay = fy - y0
    return (_bilinear(image, x0, y0, ax, ay, 0), _bilinear(image, x0, y0, ax, ay, 1),
            _bilinear(image, x0, y0, ax, ay, 2))


@njit(cache=True)
def _bilinear(image, x0, y0, ax, ay, c):
    return np.float32((1 - ax) * (1 - ay) * image[y0, x0, c] + ax * (1 - ay) * image[y0, x0 + 1, c]
                      + (1 - ax) * ay * image[y0 + 1, x0, c] + ax * ay * image[y0 + 1, x0 + 1, c])
