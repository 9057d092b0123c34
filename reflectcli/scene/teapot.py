"""The Utah teapot, tessellated from Newell's 32 bicubic Bezier patches.

Evaluating the patches ourselves (rather than shipping a fixed mesh) lets scenes pick the
tessellation, and the patch derivatives give exact smooth normals. Coordinates stay in the
data's native z-up frame (spout toward +x); scenes rotate by -90 degrees about x for y-up.
"""

from __future__ import annotations

import functools
import json
from importlib import resources

import numpy as np

from reflectcli.scene.mesh import Mesh
from reflectcli.scene.primitives import grid_mesh

# Grid points closer than this (native units; the teapot is ~6 across) are one vertex.
_WELD_CELL = 1e-7  # grid cell of the seam weld (model units; the teapot is ~3 wide)
# Below this |du x dv| the patch is pinched (lid top, bottom centre) and the face normal wins.
_DEGENERATE_NORMAL = 1e-9


def _control_points() -> np.ndarray:
    """(32, 4, 4, 3) control nets: [patch, u row, v column, xyz]."""
    text = resources.files("reflectcli").joinpath("data/utah-teapot.json").read_text("utf-8")
    data = json.loads(text)
    points = np.asarray(data["points"], dtype=np.float64)
    index = np.asarray(data["patches"], dtype=np.int64) - int(data.get("index_base", 1))
    return points[index].reshape(-1, 4, 4, 3)


def _bernstein(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cubic Bernstein basis and its derivative at t: two (len(t), 4) arrays."""
    s = 1.0 - t
    basis = np.stack([s**3, 3 * t * s**2, 3 * t**2 * s, t**3], axis=1)
    deriv = np.stack([-3 * s**2, 3 * s**2 - 6 * t * s, 6 * t * s - 3 * t**2, 3 * t**2], axis=1)
    return basis, deriv


def _signed_volume(mesh: Mesh) -> float:
    c = mesh.corners
    return float(np.einsum("ij,ij->i", c[:, 0], np.cross(c[:, 1], c[:, 2])).sum() / 6.0)


def weld_points(points: np.ndarray, cell: float = _WELD_CELL) -> np.ndarray:
    """(..., 3) points with every group that shares a `cell`-sized grid cell replaced by its
    first member (in flat index order), so that shared vertices are bit-identical.

    Adjacent patches share their boundary control points, but evaluating the same boundary
    curve from two nets (summed in another order, or with t and 1 - t swapped) differs in
    the last bits: triangles of the two patches then meet along slightly different edges,
    and a ray (or a rasterized pixel center) can pass between them, a pinhole. Those copies
    differ by ~1e-15 and distinct vertices by over 1e-4, so a 1e-7 grid groups exactly the
    copies; a test holds it to a KD-tree weld at 1e-9 (tests/naive.py) for every size.
    """
    flat = points.reshape(-1, 3)
    keys = np.round(flat / cell).astype(np.int64)
    _, label = np.unique(keys, axis=0, return_inverse=True)
    label = label.reshape(-1)
    first = np.full(label.max() + 1, len(flat))
    np.minimum.at(first, label, np.arange(len(flat)))
    return flat[first[label]].reshape(points.shape)


def patch_points(subdivisions: int) -> np.ndarray:
    """(patches, n + 1, n + 1, 3) points of every patch's n x n grid, before welding."""
    b, _ = _bernstein(np.linspace(0.0, 1.0, subdivisions + 1))
    return np.einsum("ai,bj,pijk->pabk", b, b, _control_points())


@functools.lru_cache(maxsize=16)
def _tessellate(subdivisions: int) -> Mesh:
    nets = _control_points()
    t = np.linspace(0.0, 1.0, subdivisions + 1)
    b, db = _bernstein(t)
    # grids indexed [patch, u, v]: rows follow u, columns follow v
    pos = weld_points(patch_points(subdivisions))
    d_u = np.einsum("ai,bj,pijk->pabk", db, b, nets)
    d_v = np.einsum("ai,bj,pijk->pabk", b, db, nets)
    # grid_mesh's front is d/dcol x d/drow = Sv x Su, which is outward for Newell's data;
    # the volume check below keeps that true whatever the data's orientation.
    normals = np.cross(d_v, d_u)
    length = np.linalg.norm(normals, axis=-1, keepdims=True)
    degenerate = length[..., 0] < _DEGENERATE_NORMAL
    normals = normals / np.where(degenerate[..., None], 1.0, length)
    normals[degenerate] = np.nan  # marker, replaced by the face normal per triangle
    uu, vv = np.meshgrid(t, t, indexing="ij")
    uvs = np.broadcast_to(np.stack([uu, vv], axis=-1), pos.shape[:-1] + (2,))
    mesh = grid_mesh(pos, uvs, normals).without_degenerate()
    corner_normals = mesh.normals
    face = np.broadcast_to(mesh.face_normals()[:, None, :], corner_normals.shape)
    corner_normals = np.where(np.isnan(corner_normals), face, corner_normals)
    mesh = Mesh(mesh.corners, mesh.uvs, corner_normals)
    if _signed_volume(mesh) < 0:
        mesh = Mesh(mesh.corners[:, ::-1], mesh.uvs[:, ::-1], -mesh.normals[:, ::-1])
    for array in (mesh.corners, mesh.uvs, mesh.normals):
        array.flags.writeable = False
    return mesh


def teapot(subdivisions: int = 8) -> Mesh:
    """Utah teapot, z-up, about x in [-3, 3.43], y in [-2, 2], z in [0, 3.15].

    Each patch is sampled on a (subdivisions+1)^2 grid, and grid points shared by
    neighbouring patches are welded (bit-identical), so the surface has no cracks along the
    patch seams; what stays open is Newell's own design (the gap around the lid, the spout's
    mouth, the handle and spout ends inside the body). UV: per patch, (u, v) = the patch
    parameters in [0,1] (u along the control-net rows, v along the columns), so the texture
    repeats once per patch. Normals come from the patch derivatives, oriented outward, with
    the face normal where the patch is pinched; zero-area triangles are dropped. Results are
    cached per level and returned with read-only arrays (copy before mutating).
    """
    if int(subdivisions) < 1:
        raise ValueError(f"teapot subdivisions must be >= 1, got {subdivisions}")
    return _tessellate(int(subdivisions))
