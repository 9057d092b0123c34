"""Write reflectcli/data/warm-up-wave.ply: the warm-up scene's mesh reflector.

A sheet z = 0.3 sin(pi x) over [-1, 1]^2 (8 x 8 cells, 128 triangles, front = +z, wound
counter-clockwise seen from +z): its valley (x < 0) is concave and its hill convex, so
`virtual` splits it into two parts and the warm-up (reflectcli/warmup.py) compiles the
kernels of a reflector of several parts, as a render of scenes/mask.toml runs them.
Deterministic: `python scripts/make_warm_wave.py` from the repository root (or pass an
output path) writes the same bytes.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

CELLS = 8
AMPLITUDE = 0.3


def make_wave():
    """The sheet as a trimesh.Trimesh."""
    import trimesh

    s = np.linspace(-1.0, 1.0, CELLS + 1)
    gx, gy = np.meshgrid(s, s)  # rows along y, columns along x
    vertices = np.stack([gx, gy, AMPLITUDE * np.sin(np.pi * gx)], axis=-1).reshape(-1, 3)
    idx = np.arange(gx.size).reshape(gx.shape)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                            np.stack([a, c, d], -1).reshape(-1, 3)])
    return trimesh.Trimesh(vertices, faces, process=False)


def main(argv: list[str]) -> int:
    from make_mask import write_ply  # this folder's: run as a script, it is on the path

    root = Path(__file__).resolve().parents[1]
    out = Path(argv[1]) if len(argv) > 1 else root / "reflectcli" / "data" / "warm-up-wave.ply"
    write_ply(make_wave(), out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
