"""Load a user mesh file (OBJ, PLY, GLB, STL) into the renderer's `Mesh` triangle soup.

trimesh does the parsing; here we only decide the shading normals: smooth vertex normals
unless they disagree with the face by more than 45 degrees, so hard edges stay hard.
"""

from __future__ import annotations

import functools
import os
import warnings
from pathlib import Path

import numpy as np

from reflectcli.scene.mesh import Mesh

_SMOOTH_LIMIT_COS = float(np.cos(np.radians(45.0)))


def load_mesh_file(path: str | Path) -> Mesh:
    """Read `path` with trimesh (scenes are merged) into object-space corners, uvs, normals.

    UVs come from the file's texture coordinates when present, else zeros. Raises
    FileNotFoundError for a missing file and ValueError when trimesh cannot read it or the
    result has no triangles.
    """
    import trimesh  # slow to import; only mesh-file scenes pay for it

    from ..config.files import file_problem
    from ..config.limits import MAX_MESH_BYTES, MAX_NUMBER, MAX_TRIANGLES
    from .gltf import gltf_problem

    file = Path(path)
    reason = file_problem(str(file), MAX_MESH_BYTES, "mesh file")
    if reason is not None:
        raise FileNotFoundError(f"{reason}: {file}")
    reason = gltf_problem(str(file), MAX_MESH_BYTES)
    if reason is not None:
        raise ValueError(f"mesh file {file}: {reason}")
    try:
        with warnings.catch_warnings():  # overflow in its vertex merge: our line says why
            warnings.simplefilter("ignore")
            loaded = trimesh.load(file, force="mesh",
                                  resolver=_limited_resolver(str(file), MAX_MESH_BYTES))
    except Exception as exc:  # trimesh raises many types for bad or unknown files
        why = str(exc).splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ValueError(f"cannot read mesh file {file}: {why}") from exc
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise ValueError(f"mesh file {file} contains no triangles")
    if len(loaded.faces) > MAX_TRIANGLES:
        raise ValueError(f"mesh file {file} has {len(loaded.faces)} triangles; "
                         f"the limit is {MAX_TRIANGLES}")
    if not np.isfinite(loaded.vertices).all():
        raise ValueError(f"mesh file {file} has non-finite vertex coordinates")
    # past 1e9 trimesh's vertex merge (coordinates over its 1e-8 tolerance, as int64)
    # overflows and joins vertices that are apart: no `fit` or transform can undo that. The
    # coordinate limit itself holds in world space (scene/extent.py), after both.
    if np.abs(loaded.vertices).max() > MAX_NUMBER:
        raise ValueError(f"mesh file {file} has coordinates past +-{MAX_NUMBER:g}")

    faces = np.asarray(loaded.faces, dtype=np.int64)
    vertices = np.asarray(loaded.vertices, dtype=np.float64)
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise ValueError(f"mesh file {file} has faces naming vertices it does not have "
                         f"(index {faces.max()} of {len(vertices)} vertices)")
    corners = vertices[faces]
    n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    keep = length[:, 0] > 0
    if not keep.any():
        raise ValueError(f"mesh file {file} contains only zero-area triangles")
    faces, corners = faces[keep], corners[keep]
    face_normals = n[keep] / length[keep]

    uv = getattr(loaded.visual, "uv", None)
    if uv is not None and len(uv) == len(vertices):
        uvs = np.asarray(uv, dtype=np.float64)[faces, :2]
        if not np.isfinite(uvs).all() or np.abs(uvs).max() > MAX_NUMBER:
            # a texture lookup would make NaN pixels (refused only when the frame is written)
            raise ValueError(f"mesh file {file} has texture coordinates that are not finite "
                             f"or past +-{MAX_NUMBER:g}")
    else:
        uvs = np.zeros(faces.shape + (2,))

    vertex_normals = np.asarray(loaded.vertex_normals, dtype=np.float64)[faces]
    vn_length = np.linalg.norm(vertex_normals, axis=2, keepdims=True)
    vertex_normals = vertex_normals / np.where(vn_length > 0, vn_length, 1.0)
    flat = np.broadcast_to(face_normals[:, None, :], vertex_normals.shape)
    agree = np.einsum("fck,fck->fc", vertex_normals, flat) >= _SMOOTH_LIMIT_COS
    normals = np.where(agree[..., None], vertex_normals, flat)
    return Mesh(corners, uvs, normals)


def _limited_resolver(path: str, limit: int):
    """trimesh's resolver for the files a mesh file names (OBJ materials and textures, glTF
    buffers), reading only regular files within `limit` bytes in all: a file past it, a pipe
    or a device is not there for trimesh (a missing texture is skipped; a missing buffer
    fails the load)."""
    from trimesh.resolvers import FilePathResolver

    from ..config.files import file_problem

    class Limited(FilePathResolver):
        budget = limit - os.path.getsize(path)

        def absolute(self, name: str):
            found = super().absolute(name)
            if found.exists():
                reason = file_problem(str(found), max(self.budget, 0), "mesh file's asset")
                if reason is not None:
                    raise ValueError(f"{name}: {reason}")
                Limited.budget -= found.stat().st_size
            return found

    return Limited(path)


def resolve(source: str, path: str) -> str:
    """A path written in a config file is relative to that file."""
    return os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(source)), path))


@functools.lru_cache(maxsize=32)
def cached_mesh_file(path: str) -> Mesh:
    """load_mesh_file, kept for files read again (a scene rebuilt, a mesh used twice)."""
    return load_mesh_file(path)
