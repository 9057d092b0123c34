"""A procedural music-room furniture set: clutter for reflections, at a chosen triangle budget.

Benchmarks need scenes whose triangle count is a dial, but whose look stays the same; so the
furniture layout is fixed and only tessellation changes. Curved parts share one segment count,
and the chandelier ring absorbs the remainder so the total lands close to the request.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from reflectcli.scene.mesh import Mesh
from reflectcli.scene.primitives import box, cone, cylinder, torus, uv_sphere

# Canonical layout (metres): furniture within x in [-5, 5], z in [-4, 4], up to y = 2.0,
# plus a chandelier hanging 0.7 below its ceiling anchor; the whole set is scaled to fit.
_HALF_X, _HALF_Z, _HEIGHT = 5.0, 4.0, 3.0
_WALL_CLEARANCE = 0.06  # fraction of the room size kept free in front of every wall
_CHANDELIER_RING = (0.55, 0.04)  # major, minor radius


def _translate(x: float, y: float, z: float) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def _scale(x: float, y: float, z: float) -> np.ndarray:
    return np.diag([x, y, z, 1.0])


def _rotate(axis: int, angle: float) -> np.ndarray:
    """Right-handed rotation by `angle` radians about axis 0 (x), 1 (y) or 2 (z)."""
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m = np.eye(4)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


Placed = list[tuple[Mesh, np.ndarray]]
_I = np.eye(4)


def _piano(n: int) -> Placed:
    """Grand piano: elliptic case, keyboard, legs and a propped lid, front toward +z."""
    ellipse = _scale(0.8, 1.0, 1.35)
    hinge = _translate(0.8, 0.97, 0) @ _rotate(2, -np.radians(28)) @ _translate(-0.8, 0, 0)
    leg = cylinder(0.06, 0.62, max(n // 2, 6))
    bench = [box([-0.45, 0.45, 1.85], [0.45, 0.52, 2.2])] + [
        box([x - 0.03, 0.0, z - 0.03], [x + 0.03, 0.45, z + 0.03])
        for x in (-0.4, 0.4)
        for z in (1.9, 2.15)
    ]
    return [
        (cylinder(1.0, 0.35, n), _translate(0, 0.62, 0) @ ellipse),
        (cylinder(1.0, 0.03, n), hinge @ ellipse),
        (box([-0.75, 0.62, 1.15], [0.75, 0.9, 1.55]), _I),
        (box([-0.62, 0.97, -0.02], [-0.58, 1.72, 0.02]), _I),
        *[(leg, _translate(x, 0, z)) for x, z in ((-0.55, 1.0), (0.55, 1.0), (0.0, -1.1))],
        *[(m, _I) for m in bench],
    ]


def _music_stand(n: int) -> Placed:
    """Pole on a conical foot, with a desk tilted back toward the player at +z."""
    seg = max(n // 2, 6)
    tilt = _translate(0, 1.12, 0) @ _rotate(0, -np.radians(20))
    return [
        (cone(0.25, 0.08, seg), _I),
        (cylinder(0.015, 1.12, seg), _I),
        (box([-0.25, 0.0, -0.01], [0.25, 0.35, 0.01]), tilt),
        (box([-0.25, -0.02, -0.01], [0.25, 0.0, 0.06]), tilt),
    ]


def _chair() -> Placed:
    """Seat, back (toward +z) and four legs; 72 triangles."""
    legs = [
        box([x - 0.02, 0.0, z - 0.02], [x + 0.02, 0.45, z + 0.02])
        for x in (-0.2, 0.2)
        for z in (-0.2, 0.2)
    ]
    seat = box([-0.23, 0.45, -0.23], [0.23, 0.49, 0.23])
    back = box([-0.23, 0.49, 0.2], [0.23, 0.95, 0.24])
    return [(m, _I) for m in (seat, back, *legs)]


def _drum_kit(n: int) -> Placed:
    """Bass drum on its side, toms, snare, floor tom and two cymbals on stands."""
    seg = max(n // 2, 6)
    parts = [(cylinder(0.28, 0.4, n), _translate(0, 0.28, 0.2) @ _rotate(0, -np.pi / 2))]
    for r, h, x, y, z in (
        (0.15, 0.2, -0.2, 0.6, 0.0),
        (0.15, 0.2, 0.2, 0.6, 0.0),
        (0.18, 0.14, -0.45, 0.55, 0.45),
        (0.2, 0.45, 0.5, 0.0, 0.45),
    ):
        parts.append((cylinder(r, h, n), _translate(x, y, z)))
    stand, cymbal = cylinder(0.012, 1.05, seg), cone(0.22, 0.04, n)
    for x, z in ((-0.7, -0.1), (0.75, -0.1)):
        parts += [(stand, _translate(x, 0, z)), (cymbal, _translate(x, 1.05, z))]
    return parts


def _string_instrument(n: int, size: float, sphere: Mesh) -> Placed:
    """Cello-like (size 1) or guitar-like (smaller) body from two squashed spheres and a neck."""
    # tilt back on the endpin, lifted so the pin's rim stays on the floor
    lean = _translate(0, 0.002 * size, 0) @ _rotate(0, np.radians(8)) @ _scale(size, size, size)
    return [
        (sphere, lean @ _translate(0, 0.45, 0) @ _scale(0.22, 0.28, 0.11)),
        (sphere, lean @ _translate(0, 0.8, 0) @ _scale(0.18, 0.2, 0.1)),
        (box([-0.025, 0.95, -0.03], [0.025, 1.35, 0.03]), lean),
        (cylinder(0.012, 0.2, max(n // 2, 6)), lean),
    ]


def _chandelier(n: int, ring_major: int, ring_minor: int, sphere: Mesh) -> Placed:
    """Hangs below y=0 (its ceiling anchor): rod, ring (the budget filler), bulbs, centre."""
    major, minor = _CHANDELIER_RING
    angles = np.linspace(0.0, 2 * np.pi, 6, endpoint=False)
    bulb = _scale(0.07, 0.07, 0.07)
    return [
        (cylinder(0.02, 0.45, max(n // 2, 6)), _translate(0, -0.45, 0)),
        (torus(major, minor, ring_major, ring_minor), _translate(0, -0.5, 0)),
        *[(sphere, _translate(major * np.cos(a), -0.42, major * np.sin(a)) @ bulb) for a in angles],
        (sphere, _translate(0, -0.55, 0) @ _scale(0.12, 0.12, 0.12)),
    ]


def _place(parts: Placed, x: float, z: float, yaw: float) -> Placed:
    """Compose a floor placement onto each part's matrix, so every mesh moves only once."""
    m = _translate(x, 0, z) @ _rotate(1, yaw)
    return [(p, m @ local) for p, local in parts]


def _floor_set(n: int, rng: np.random.Generator, sphere: Mesh) -> Placed:
    """Everything standing on the floor, in canonical coordinates."""

    def jitter(x: float, z: float, yaw_deg: float) -> tuple[float, float, float]:
        dx, dz = rng.uniform(-0.1, 0.1, 2)
        return x + dx, z + dz, np.radians(yaw_deg + rng.uniform(-12, 12))

    parts = _place(_piano(n), -2.3, -1.4, np.radians(20))
    stand = _music_stand(n)
    chair = _chair()
    for x, z, yaw in ((0.6, 0.9, -15), (1.9, 1.3, 0), (3.2, 0.9, 15)):
        parts += _place(stand, *jitter(x, z, yaw))
        parts += _place(chair, *jitter(x, z + 0.9, yaw))
    for x, z, yaw in ((-1.0, 2.9, 180), (0.0, 3.0, 180), (3.9, 2.9, 200)):
        parts += _place(chair, *jitter(x, z, yaw))
    parts += _place(_drum_kit(n), 3.1, -2.4, np.radians(-30))
    cello = _string_instrument(n, 1.0, sphere)
    guitar = _string_instrument(n, 0.7, sphere)
    for inst, x, z in ((cello, 0.2, -3.2), (cello, 0.9, -3.3), (guitar, -3.8, 2.9)):
        parts += _place(inst, *jitter(x, z, 0))
    parts += _place(guitar, *jitter(-3.1, 3.1, 10))
    return parts


def _ring_segments(remaining: int) -> tuple[int, int]:
    """(major, minor) torus segments whose 2*major*minor triangles come closest to `remaining`."""
    minor = max(4, int(round(np.sqrt(max(remaining, 0) / 2.0) / 4.0)))
    major = max(8, int(round(max(remaining, 0) / (2.0 * minor))))
    return major, minor


def _detail_for(budget: int, count: Callable[[int], int]) -> int:
    """Even curved-segment count whose fixed part uses about 85% of the budget (at least 6).

    For even n >= 12 every part's count is exactly quadratic in n, so three cheap probes
    fit it and no large trial builds are needed; the ring filler absorbs what is left.
    """
    probes = np.array([12.0, 24.0, 48.0])
    a, b, c = np.polyfit(probes, [count(int(p)) for p in probes], 2)
    target = 0.85 * budget - c
    n = (-b + np.sqrt(b * b + 4 * a * max(target, 0.0))) / (2 * a) if a > 0 else target / b
    return max(6, 2 * int(n // 2))


def music_room_clutter(
    triangles: int,
    bounds_min: Sequence[float],
    bounds_max: Sequence[float],
    seed: int = 7,
) -> Mesh:
    """Piano, stands, chairs, drums, cellos/guitars and a chandelier inside a room's bounds.

    Furniture stands on the floor (y = bounds_min[1]); the chandelier hangs from the ceiling.
    The set is scaled uniformly to fit and keeps 6% of the room size clear of every wall and
    the ceiling, so wall mirrors stay unobstructed. The total lands within a few percent of
    `triangles` (2,000 to ~1,000,000); `seed` only jitters placement, never the count.
    UVs are those of the primitives (each part's own layout).
    """
    lo = np.asarray(bounds_min, dtype=np.float64)
    hi = np.asarray(bounds_max, dtype=np.float64)
    size = hi - lo
    if np.any(size <= 0):
        raise ValueError(f"room bounds are empty: {lo} .. {hi}")
    clear = _WALL_CLEARANCE * size
    avail = size - 2 * clear
    k = min(avail[0] / (2 * _HALF_X), avail[2] / (2 * _HALF_Z), (size[1] - clear[1]) / _HEIGHT)
    centre = 0.5 * (lo + hi)

    def parts(n: int, ring_major: int = 8, ring_minor: int = 4) -> tuple[Placed, Placed]:
        sphere = uv_sphere(1.0, n)  # one tessellation shared by every round part
        floor = _floor_set(n, np.random.default_rng(seed), sphere)
        return floor, _chandelier(n, ring_major, ring_minor, sphere)

    def fixed_count(n: int) -> int:
        """Triangles of everything except the chandelier ring."""
        floor, hanging = parts(n)
        return sum(m.triangle_count for m, _ in floor + hanging) - 2 * 8 * 4

    n = _detail_for(int(triangles), fixed_count)
    ring_major, ring_minor = _ring_segments(int(triangles) - fixed_count(n))
    floor, hanging = parts(n, ring_major, ring_minor)
    to_room = _translate(centre[0], lo[1], centre[2]) @ _scale(k, k, k)
    hang = _translate(centre[0], hi[1] - clear[1], centre[2]) @ _scale(k, k, k)
    world = [m.transformed(to_room @ local) for m, local in floor]
    world += [m.transformed(hang @ local) for m, local in hanging]
    return Mesh.concatenate(world)
