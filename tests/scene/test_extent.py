"""The world-space coordinate limit's reach of moving objects: exact at keys and between keys
of one rotation, a bound (never an underestimate) between keys that rotate."""

from __future__ import annotations

import numpy as np

from reflectcli.config.objects import TransformKey
from reflectcli.scene import primitives
from reflectcli.scene.extent import motion_reach, reach


def _exact(mesh, keys, frames) -> float:
    """The largest world coordinate over every frame, transformed as build.transform_at."""
    from reflectcli.scene.build import transform_at

    class Obj:
        motion = keys

    return max(reach(mesh.transformed(transform_at(Obj, f)).corners) for f in frames)


def test_motion_reach_is_exact_without_rotation():
    mesh = primitives.box((-1, -1, -1), (1, 2, 1))
    keys = [TransformKey(frame=0, translate=(5, 0, 0)),
            TransformKey(frame=10, translate=(-3, 7, 0), scale=(2, 3, 1))]
    assert np.isclose(motion_reach(mesh, keys), _exact(mesh, keys, range(11)))


def test_motion_reach_bounds_a_rotation_between_keys():
    mesh = primitives.box((-1, -1, -1), (1, 1, 1))
    keys = [TransformKey(frame=0), TransformKey(frame=8, rotate=(0, 90, 0), scale=2.0)]
    exact = _exact(mesh, keys, range(9))
    found = motion_reach(mesh, keys)
    assert found >= exact - 1e-9
    assert found <= 2.0 * np.sqrt(3) + 1e-9  # the bound: scale times the box's radius
