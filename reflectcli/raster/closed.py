"""Faces an eye cannot see: a closed piece (Mesh.pieces: a solid, or each closed part of a
composite such as the music room's clutter) whose faces all turn outward, seen from an eye
outside it, shows front faces only (a ray from outside enters it through a front face
first, nearer than any back face it leaves by; other pieces do not change that), unless a
clip plane cuts it open. The primary pass flags such pieces' triangles FLAG_CULL_BACK (on
four-spheres the spheres' far halves were half of the pass's triangles: the draw 3.4 ->
2.4 ms at 2 threads); a planar mirror's reflection pass does the same from the reflected
eye for the pieces its clip plane leaves whole (FLAG_CULL_FRONT on odd levels, where the
reflection flips the screen winding).

The one pixel this can change: a centre exactly on a silhouette edge that a front and a back
face share, where both cover it at the same depth and the lower triangle index won the tie
(the back face, when it came first); the front face now has it."""

from __future__ import annotations

import math

import numpy as np

from ..camera import Camera
from ..scene.types import Geometry, Triangles
from .rasterize import (
    FLAG_CULL_BACK,
    FLAG_CULL_FRONT,
    FLAG_MIRROR,
    FLAG_SKIP,
    RasterWorkspace,
)


def near_reach(camera: Camera) -> float:
    """How far from the eye the near plane reaches inside the view (its corners' distance),
    a little widened: a surface no closer than this to the eye is never cut by it."""
    t = math.tan(math.radians(camera.fov_y) / 2.0)
    return 1.01 * camera.near * math.sqrt(1.0 + t * t * (1.0 + camera.aspect ** 2))


def seen_from_outside(geometry: Geometry, camera: Camera) -> np.ndarray | None:
    """(K,) bool per closed piece: a piece whose world box, widened by `near_reach`, does
    not hold the eye (outside it in some axis; NaN boxes never). None when the geometry
    knows no closed piece."""
    boxes = geometry.closed_boxes
    if boxes is None:
        return None
    return _outside(boxes, np.asarray(camera.eye, np.float64), near_reach(camera))


def hidden_back_faces(geometry: Geometry, camera: Camera) -> np.ndarray | None:
    """`seen_from_outside`: the pieces whose back faces the eye cannot see; None when the
    geometry knows no closed piece or none is seen from outside."""
    hidden = seen_from_outside(geometry, camera)
    return hidden if hidden is not None and hidden.any() else None


def _outside(boxes: np.ndarray, eye: np.ndarray, reach: float) -> np.ndarray:
    """(K,) bool: boxes (K, 6) widened by `reach` that do not hold `eye` (NaN: False)."""
    with np.errstate(invalid="ignore"):
        return ((eye < boxes[:, :3] - reach) | (eye > boxes[:, 3:] + reach)).any(axis=1)


def _on_one_side(boxes: np.ndarray, plane: np.ndarray) -> np.ndarray:
    """(K,) bool: boxes (K, 6) wholly on one side of `plane` (4,: n, d; n . x + d), by a
    margin (a piece the plane cuts shows its inside; NaN: False)."""
    n, d = plane[:3], float(plane[3])
    center = 0.5 * (boxes[:, :3] + boxes[:, 3:])
    half = 0.5 * (boxes[:, 3:] - boxes[:, :3])
    at = center @ n + d
    spread = half @ np.abs(n)
    margin = 1e-6 * (1.0 + abs(d) + np.abs(center).max(axis=1, initial=0.0))
    with np.errstate(invalid="ignore"):
        return (at - spread > margin) | (at + spread < -margin)


def flagged(piece: np.ndarray | None, hidden: np.ndarray | None, flags: np.ndarray,
            flag: int) -> np.ndarray:
    """`flags` with `flag` added on the triangles of the pieces `hidden` marks (a new
    array; `flags` itself when none)."""
    if hidden is None or piece is None or not hidden.any():
        return flags
    marked = np.append(hidden, False)[piece]  # piece -1: the appended False
    return flags | np.where(marked, flag, 0).astype(np.uint8)


def primary_flags(tris: Triangles, n_objects: int, piece: np.ndarray | None,
                  hidden: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """(mirror flags, draw flags) of the primary pass: FLAG_MIRROR on the mirrors'
    triangles (what later passes take), and those with FLAG_CULL_BACK on the triangles of
    the pieces `hidden` marks (the primary pass's alone: a reflected eye sees other
    faces). Both read-only."""
    mirror = (tris.surface >= n_objects).astype(np.uint8) * np.uint8(FLAG_MIRROR)
    mirror.flags.writeable = False
    draw = flagged(piece, hidden, mirror, FLAG_CULL_BACK)
    draw.flags.writeable = False
    return mirror, draw


def primary_pass_flags(geometry: Geometry, camera: Camera, n_objects: int,
                       workspace: RasterWorkspace | None) -> tuple[np.ndarray, np.ndarray]:
    """`primary_flags` of the geometry's triangles for this camera, kept in `workspace`
    while the triangles and the pieces whose back faces are hidden stay the same."""
    tris = geometry.all_triangles()
    ws = RasterWorkspace() if workspace is None else workspace
    # which pieces, kept while the boxes and the eye stay (50-130 us of numpy a frame)
    eye = np.asarray(camera.eye, np.float64)
    hidden = ws.kept("primary_hidden", geometry.closed_boxes,
                     (eye.tobytes(), near_reach(camera)),
                     lambda: hidden_back_faces(geometry, camera))
    key = (n_objects, None if hidden is None else hidden.tobytes())
    return ws.kept("primary_flags", tris, key,
                   lambda: primary_flags(tris, n_objects, geometry.closed_piece, hidden))


def reflection_pass_flags(geometry: Geometry, flags: np.ndarray, mirror_surface: int,
                          eye: np.ndarray, plane: np.ndarray, camera: Camera, level: int,
                          workspace: RasterWorkspace) -> np.ndarray:
    """The flags of a planar mirror's reflection pass at `level` (1: seen from the real
    eye): `flags` (the primary pass's mirror flags), FLAG_SKIP on the mirror's own
    triangles, and the faces turned away from the reflected `eye` (world) culled on the
    pieces it sees from outside (`near_reach`) that the pass's clip `plane` (4,: the
    mirror's, kept side >= 0) does not cut. A reflection flips the screen winding, so on
    odd levels those faces are the screen's front faces (FLAG_CULL_FRONT). Kept in
    `workspace` (one entry per mirror and parity) while the same faces are culled."""
    tris = geometry.all_triangles()
    boxes = geometry.closed_boxes
    hidden = None
    if boxes is not None:
        hidden = (_outside(boxes, np.asarray(eye, np.float64), near_reach(camera))
                  & _on_one_side(boxes, np.asarray(plane, np.float64)))
    odd = level % 2 == 1
    key = (id(flags), None if hidden is None else hidden.tobytes())

    def make() -> tuple[np.ndarray, np.ndarray]:
        own = np.where(tris.surface == mirror_surface, FLAG_SKIP, 0).astype(np.uint8)
        out = flagged(geometry.closed_piece, hidden, flags | own,
                      FLAG_CULL_FRONT if odd else FLAG_CULL_BACK)
        out.flags.writeable = False
        return out, flags  # `flags` held: its id in the key stays its own

    name = f"reflection_flags:{mirror_surface}:{int(odd)}"
    return workspace.kept(name, tris, key, make)[0]
