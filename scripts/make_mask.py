"""Write scenes/assets/mask.ply: a face-like mask reflector of convex and concave pieces.

Stand-in for Ofek & Rappoport's Fig. 19 ("a mask composed of several convex and concave
pieces"): a height field z = h(x, y) over an elliptical outline about 2 wide (x) and 2.4 high
(y), front = +z (triangles counter-clockwise seen from +z), made of pieces that are each
wholly convex or wholly concave, meeting along creases:

- a convex shell (paraboloid) for the face,
- two convex cheeks and a convex nose ridge standing out of it (the maximum of the shell and
  their paraboloids: the pieces meet in valley creases),
- two concave eye sockets sunk into it (the minimum with upward paraboloids: rim creases).

Pieces rather than smooth bumps on purpose: a smooth bump on a shell is ringed by saddle
regions, neither convex nor concave, where reflection cells overlap, which the paper
leaves to manual decomposition. Deterministic: run `python scripts/make_mask.py` from the
repository root (or pass an output path) and the same file comes out.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HALF_W, HALF_H = 1.0, 1.2  # outline semi-axes (x, y)
CELLS_X, CELLS_Y = 60, 72  # grid cells (8,640 triangles)


def _cap(x, y, cx, cy, rx, ry, top):
    """A paraboloid with its apex `top` at (cx, cy) and radii of curvature rx, ry."""
    return top - (x - cx) ** 2 / (2.0 * rx) - (y - cy) ** 2 / (2.0 * ry)


def height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The mask's relief z(x, y)."""
    shell = _cap(x, y, 0.0, 0.0, 2.8, 4.8, 0.3)  # the convex face
    z = shell
    for side in (-1.0, 1.0):
        z = np.maximum(z, _cap(x, y, side * 0.5, -0.4, 0.35, 0.35, 0.38))  # cheeks
    z = np.maximum(z, _cap(x, y, 0.0, 0.0, 0.06, 0.9, 0.42))  # nose ridge
    for side in (-1.0, 1.0):  # eye sockets: bowls whose bottom sits 0.1 below the shell
        bottom = _cap(side * 0.42, 0.4, 0.0, 0.0, 2.8, 4.8, 0.3) - 0.1
        z = np.minimum(z, -_cap(x, y, side * 0.42, 0.4, 0.3, 0.3, -bottom))
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


def write_ply(mesh, out: Path) -> None:
    """The mesh as binary PLY at `out`, through a temporary name (the same bytes each run)."""
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_bytes(mesh.export(file_type="ply", encoding="binary"))
    tmp.replace(out)
    print(f"{out}: {len(mesh.vertices)} vertices, {len(mesh.faces)} triangles")


def main(argv: list[str]) -> int:
    out = (
        Path(argv[1])
        if len(argv) > 1
        else (Path(__file__).resolve().parents[1] / "scenes" / "assets" / "mask.ply")
    )
    write_ply(make_mask(), out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
