"""The procedural music room: triangle budget, determinism, and clearance from the walls."""

from __future__ import annotations

import numpy as np
import pytest

from reflectcli.scene.procedural import music_room_clutter

LO, HI = (-5.0, 0.0, -4.0), (5.0, 3.5, 4.0)


@pytest.mark.parametrize("budget", [2_000, 20_000, 200_000])
def test_triangle_budget(budget):
    m = music_room_clutter(budget, LO, HI)
    assert abs(m.triangle_count - budget) <= 0.1 * budget


def test_deterministic_per_seed():
    a = music_room_clutter(5_000, LO, HI, seed=3)
    b = music_room_clutter(5_000, LO, HI, seed=3)
    c = music_room_clutter(5_000, LO, HI, seed=4)
    assert np.array_equal(a.corners, b.corners) and np.array_equal(a.uvs, b.uvs)
    assert a.triangle_count == c.triangle_count
    assert not np.array_equal(a.corners, c.corners)


@pytest.mark.parametrize(
    ("lo", "hi"), [(LO, HI), ((0.0, -1.0, 0.0), (4.0, 2.0, 12.0)), ((-1, 0, -1), (1, 5, 1))]
)
def test_inside_bounds_clear_of_walls(lo, hi):
    m = music_room_clutter(10_000, lo, hi)
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    margin = 0.05 * (hi - lo)
    pts = m.corners.reshape(-1, 3)
    assert pts[:, 1].min() >= lo[1] - 1e-9  # stands on the floor, not below it
    assert np.isclose(pts[:, 1].min(), lo[1])
    assert pts[:, 1].max() <= hi[1] - margin[1]
    for axis in (0, 2):
        assert pts[:, axis].min() >= lo[axis] + margin[axis]
        assert pts[:, axis].max() <= hi[axis] - margin[axis]


def test_clean_mesh():
    m = music_room_clutter(20_000, LO, HI)
    assert m.areas().min() > 0
    assert np.allclose(np.linalg.norm(m.normals, axis=2), 1.0)
    assert np.isfinite(m.uvs).all()
