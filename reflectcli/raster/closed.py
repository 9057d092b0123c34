"""Back faces the real camera cannot see: a closed surface whose faces all turn outward
(scene.build.closed_outward), seen from an eye outside it, shows front faces only (a ray
from outside enters it through a front face first), unless the near plane cuts it open.
Its triangles are flagged FLAG_CULL_BACK in the primary pass: on four-spheres the spheres'
far halves were half of the pass's triangles (the draw 3.4 -> 2.4 ms at 2 threads).

The one pixel this can change: a centre exactly on a silhouette edge that a front and a back
face share, where both cover it at the same depth and the lower triangle index won the tie
(the back face, when it came first); the front face now has it. No render of the bundled
scenes changed."""

from __future__ import annotations

import math

import numpy as np

from ..camera import Camera
from ..scene.types import Geometry, Triangles
from .rasterize import FLAG_CULL_BACK, FLAG_MIRROR, RasterWorkspace


def near_reach(camera: Camera) -> float:
    """How far from the eye the near plane reaches inside the view (its corners' distance),
    a little widened: a surface no closer than this to the eye is never cut by it."""
    t = math.tan(math.radians(camera.fov_y) / 2.0)
    return 1.01 * camera.near * math.sqrt(1.0 + t * t * (1.0 + camera.aspect ** 2))


def hidden_back_faces(geometry: Geometry, camera: Camera) -> np.ndarray | None:
    """(S,) bool per surface id: a closed surface whose world box, widened by
    `near_reach`, does not hold the eye (outside it in some axis; NaN boxes, the open
    surfaces, never). None when the geometry knows no closed surface."""
    boxes = geometry.closed_boxes
    if boxes is None:
        return None
    eye = np.asarray(camera.eye, np.float64)
    reach = near_reach(camera)
    with np.errstate(invalid="ignore"):
        outside = (eye < boxes[:, :3] - reach) | (eye > boxes[:, 3:] + reach)
    hidden = outside.any(axis=1)
    return hidden if hidden.any() else None


def primary_flags(tris: Triangles, n_objects: int,
                  hidden: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """(mirror flags, draw flags) of the primary pass: FLAG_MIRROR on the mirrors'
    triangles (what later passes take), and those with FLAG_CULL_BACK on the triangles of
    the surfaces `hidden` marks (the primary pass's alone: a reflected eye sees other
    faces). Both read-only."""
    mirror = (tris.surface >= n_objects).astype(np.uint8) * np.uint8(FLAG_MIRROR)
    mirror.flags.writeable = False
    if hidden is None:
        return mirror, mirror
    draw = mirror | np.where(hidden[tris.surface], FLAG_CULL_BACK, 0).astype(np.uint8)
    draw.flags.writeable = False
    return mirror, draw


def primary_pass_flags(geometry: Geometry, camera: Camera, n_objects: int,
                       workspace: RasterWorkspace | None) -> tuple[np.ndarray, np.ndarray]:
    """`primary_flags` of the geometry's triangles for this camera, kept in `workspace`
    while the triangles and the surfaces whose back faces are hidden stay the same."""
    tris = geometry.all_triangles()
    hidden = hidden_back_faces(geometry, camera)
    key = (n_objects, None if hidden is None else hidden.tobytes())
    ws = RasterWorkspace() if workspace is None else workspace
    return ws.kept("primary_flags", tris, key, lambda: primary_flags(tris, n_objects, hidden))
