"""The coordinate limit (config/limits.py: MAX_COORDINATE) on the geometry as it is rendered:
in world space, after a mesh's `fit` and the object's transform, at every keyframe of a moving
object. Checked per field alone, a sphere of radius 1e6 scaled by 1e6 rendered, and a mesh in
millimetres scaled down to metres by its transform was refused."""

from __future__ import annotations

import numpy as np

from ..config.limits import MAX_COORDINATE
from ..config.objects import Transform
from ..errors import Problem
from ..geometry import trs_matrix

# the field named when no transform, motion or fit scaled the shape: its size
_SIZE_FIELDS = ("radius", "major_radius", "size", "height")


def reach(corners: np.ndarray) -> float:
    """The largest coordinate magnitude among `corners` (any shape; 0 for none; NaN passes
    through as NaN, so a non-finite corner fails the limit)."""
    if corners.size == 0:
        return 0.0
    return float(max(corners.max(), -corners.min()))


def motion_reach(mesh, keys) -> float:
    """The largest world coordinate a moving object's `mesh` (object space) reaches over its
    keyframes `keys`. Exact at each key, and so between two keys of the same rotation (there
    every coordinate is linear in the frame: translate and scale interpolate linearly);
    between keys that rotate, bounded by the larger translate plus the larger scale times the
    object's radius about its origin (a rotation keeps that radius)."""
    points = mesh.corners.reshape(-1, 3)
    if points.size == 0:
        return 0.0
    found = 0.0
    for key in keys:
        m = trs_matrix(key.translate, key.rotate, key.scale)
        found = max(found, reach(points @ m[:3, :3].T + m[:3, 3]))
    if any(a.rotate != b.rotate for a, b in zip(keys, keys[1:], strict=False)):
        radius = float(np.sqrt((points * points).sum(axis=1)).max())
        for a, b in zip(keys, keys[1:], strict=False):
            if a.rotate != b.rotate:
                shift = np.maximum(np.abs(a.translate), np.abs(b.translate)).max()
                scale = max(np.abs(a.scale).max(), np.abs(b.scale).max())
                found = max(found, float(shift + scale * radius))
    return found


def _field(item) -> str:
    """The field a user would change: what scaled or moved the shape, else its size."""
    if getattr(item, "motion", None):
        return "motion"
    transform = getattr(item, "transform", None)
    if transform is not None and transform != Transform():
        return "transform"
    if getattr(item, "fit", None) is not None:
        return "fit"
    if item.shape == "mesh":
        return "path"
    return next((key for key in _SIZE_FIELDS if getattr(item, key, None) is not None),
                "shape")


def too_far(section: str, index: int, item, found: float, where) -> Problem | None:
    """A Problem when `found` (the item's largest world coordinate) is past the limit;
    `where(loc)` names the file the field came from."""
    if found <= MAX_COORDINATE:
        return None
    field = _field(item)
    hint = {"path": " (`fit` or a transform scales a mesh into the scene)",
            "fit": " (`fit` centre plus half its size)"}.get(
        field, " (the shape's size and position after `fit` and the transform)")
    loc = (section, index, field)
    return Problem(where(loc), ".".join(str(p) for p in loc),
                   f"world-space coordinates reach {found:.3g}, past "
                   f"+-{MAX_COORDINATE:g}{hint}")
