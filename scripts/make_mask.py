"""Write scenes/assets/mask.ply: a face-like mask reflector of convex and concave pieces.

Stand-in for Ofek & Rappoport's Fig. 19 ("a mask composed of several convex and concave
pieces"): a smooth height field z = h(x, y) over an elliptical outline about 2 wide (x) and
2.4 high (y), front = +z (triangles counter-clockwise seen from +z):

- a gently convex base shell,
- two convex cheeks (bumps) and a convex nose ridge,
- concave hollows between the cheeks and the nose, and two concave eye sockets.

Deterministic (no randomness): run `python scripts/make_mask.py` from the repository root
(or pass an output path) and the same file comes out.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HALF_W, HALF_H = 1.0, 1.2  # outline semi-axes (x, y)
CELLS_X, CELLS_Y = 40, 48  # grid cells (3,840 triangles)


def _bump(x, y, cx, cy, sx, sy, amplitude):
    return amplitude * np.exp(-0.5 * (((x - cx) / sx) ** 2 + ((y - cy) / sy) ** 2))


def height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The mask's relief z(x, y)."""
    z = 0.3 * (1.0 - (x / 1.3) ** 2 - (y / 1.7) ** 2)  # convex shell
    for side in (-1.0, 1.0):
        z = z + _bump(x, y, side * 0.5, -0.35, 0.25, 0.25, 0.15)  # cheeks
        z = z + _bump(x, y, side * 0.25, -0.12, 0.1, 0.15, -0.06)  # hollow beside the nose
        z = z + _bump(x, y, side * 0.42, 0.38, 0.18, 0.13, -0.1)  # eye sockets
    z = z + _bump(x, y, 0.0, 0.05, 0.1, 0.3, 0.15)  # nose ridge
    z = z + _bump(x, y, 0.0, -0.25, 0.1, 0.08, 0.05)  # nose tip
    return z


def make_mask():
    """The mask as a trimesh.Trimesh (vertices, faces wound counter-clockwise from +z)."""
    import trimesh

    # a square grid over [-1, 1]^2 mapped onto the disc (smooth boundary, quads everywhere),
    # then stretched to the elliptical outline
    s = np.linspace(-1.0, 1.0, CELLS_X + 1)
    t = np.linspace(-1.0, 1.0, CELLS_Y + 1)
    gs, gt = np.meshgrid(s, t)  # rows along y, columns along x
    gx = HALF_W * gs * np.sqrt(1.0 - gt**2 / 2.0)
    gy = HALF_H * gt * np.sqrt(1.0 - gs**2 / 2.0)
    vertices = np.stack([gx, gy, height(gx, gy)], axis=-1).reshape(-1, 3)
    idx = np.arange(gx.size).reshape(gx.shape)
    a, b = idx[:-1, :-1], idx[:-1, 1:]  # (s, t), (s + ds, t)
    c, d = idx[1:, 1:], idx[1:, :-1]  # (s + ds, t + dt), (s, t + dt)
    faces = np.concatenate(
        [np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)]
    )
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    return mesh


def main(argv: list[str]) -> int:
    out = (
        Path(argv[1])
        if len(argv) > 1
        else (Path(__file__).resolve().parents[1] / "scenes" / "assets" / "mask.ply")
    )
    mesh = make_mask()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_bytes(mesh.export(file_type="ply", encoding="binary"))
    tmp.replace(out)
    print(f"{out}: {len(mesh.vertices)} vertices, {len(mesh.faces)} triangles")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
