"""Mesh objects in their own units: report their bounds and triangle count, and `fit` them
(a centre and a size) so a mesh modelled in millimetres or miles lands where meant."""

from __future__ import annotations

import logging

import numpy as np

from .mesh import Mesh

log = logging.getLogger("reflect")


def fit_mesh(mesh: Mesh, name: str, path: str, fit) -> Mesh:
    """Log the mesh's bounds; with `fit`, scale it uniformly so its largest extent is
    fit.size and move its bounding-box centre to fit.center (object space, before the
    object's transform)."""
    points = mesh.corners.reshape(-1, 3)
    lo, hi = points.min(axis=0), points.max(axis=0)
    log.info("objects.%s: %s: %d triangles, bounds [%s] .. [%s]", name, path,
             len(mesh.corners), ", ".join(f"{v:.4g}" for v in lo),
             ", ".join(f"{v:.4g}" for v in hi))
    if fit is None:
        return mesh
    extent = float((hi - lo).max())
    scale = fit.size / extent if extent > 0 else 1.0
    matrix = np.eye(4)
    matrix[:3, :3] *= scale
    matrix[:3, 3] = np.asarray(fit.center, float) - scale * (lo + hi) / 2.0
    return mesh.transformed(matrix)


def warn_textured_without_uvs(cfg, meshes) -> None:
    """A texture on a mesh without texture coordinates shows one texel: say so."""
    for obj, mesh in zip(cfg.objects, meshes, strict=True):
        material = cfg.materials.get(obj.material)
        if (obj.shape == "mesh" and mesh is not None and material is not None
                and material.kind == "texture" and not np.any(mesh.uvs != 0)):
            log.warning("objects.%s: %s has no texture coordinates; its texture '%s' shows "
                        "one texel", obj.name, obj.path, obj.material)
