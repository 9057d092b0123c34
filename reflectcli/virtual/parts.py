"""All parts of a mesh reflector worked stage by stage: each stage (tile scan, explosion
maps, map lookups, refinement) done for every part before the next, each in one parallel
region for all parts, on the parts' points joined in one set of arrays (part p's rows
row_start[p] ..). Part by part, the mask's 14 parts made each stage 14 short parallel
regions one after another, the small parts' ends leaving a thread idle, with about 20
numpy calls a part between them. Each part's answers are what it gives alone
(ExplosionPart.__call__)."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..raster.rasterize import RasterWorkspace
from ..raster.rasterize.buffers import scratch
from .explosion import build_maps_together, layer_radii, map_setup, virtual_vertices_together
from .part import ExplosionPart
from .partsetup import parts_map_setups
from .refine import BOUNDARY, EXACT, NONE, refine_parts
from .screen import screen_from_world
from .tiles import rows_of, scan_parts
from .view import face_behind


def parts_vertices(parts: list[ExplosionPart], points: np.ndarray,
                   polygons: np.ndarray | None = None,
                   ws: RasterWorkspace | None = None,
                   dtype=np.float64) -> tuple[np.ndarray, np.ndarray]:
    """(virtual (P, N, 3) world, flags (P, N)): row p is parts[p](points, polygons), the
    parts being one reflector's in one view. Stage by stage where they refine on one
    owner plane and ray grid with polygons given and maps built for their lookups (the
    technique's frames); else part by part. `ws`: a workspace to hold the arrays of the
    stages (tens of megabytes a frame: fresh, their page faults cost more than the work
    in them) and the answers, valid until its next use; else fresh arrays. `dtype`: the
    virtual points' (float32: the answers rounded as the rasterizer's gather rounds them,
    half the bytes)."""
    first = parts[0]
    if (polygons is None or first.grid is None or any(
            part.view.tiles is None or part.grid is not first.grid
            or part.view.owner is not first.view.owner or part.built is not None
            for part in parts)):
        answers = [part(points, polygons) for part in parts]
        return (np.stack([a for a, _ in answers]).astype(dtype, copy=False),
                np.stack([f for _, f in answers]))
    count = len(parts)
    n = len(points)
    points = np.ascontiguousarray(points, np.float64)
    q, r = first.grid
    reach, retry, todo = scan_parts([part.view.tiles for part in parts], points, q, r,
                                    polygons, ws)
    rows, row_start, _ = rows_of(todo)  # each part's points to find, joined
    camera = first.camera
    out = scratch(ws, "parts_out", (count, n, 3), dtype)
    flags = scratch(ws, "parts_flags", (count, n), np.bool_)
    if rows.size:
        screen = first.view.points.of(points, first.clip_from_world, camera.width,
                                      camera.height)
        m = rows.size
        row_part = np.repeat(np.arange(count, dtype=np.int64), np.diff(row_start))
        pts = scratch(ws, "parts_points", (m, 3), np.float64)
        proj = scratch(ws, "parts_screen", (m, 3), np.float64)
        seeds_retry = scratch(ws, "parts_retry", (m, 2), np.float64)
        reach_m = scratch(ws, "parts_reach", (m,), np.bool_)
        face = scratch(ws, "parts_face", (m,), np.int64)
        _gather_parts(points, np.ascontiguousarray(screen, np.float64), retry, reach, rows,
                      row_part, first.depth, first.view.triangle, _locals(parts), pts, proj,
                      seeds_retry, reach_m, face)
        # every part's explosion layers in one region, then their lookups in one (the
        # parts' layer radii in one call where they have as many layers)
        radii = [None] * count
        # build_args: (mesh, eye, center, near, far, resolution, layers, boundary)
        near, far, layers = zip(*(part.build_args[3:5] + part.build_args[6:7]
                                  for part in parts), strict=True)
        if len(set(layers)) == 1:
            radii = layer_radii(np.array(near), np.array(far), layers[0])
        together = first.together
        if together is not None and radii[0] is not None and all(
                part.together is not None and part.together[0] is together[0]
                for part in parts):
            # every part's map set-up in one kernel call (partsetup.py)
            setups, arrays = parts_map_setups(
                together[0], np.array([part.together[1] for part in parts], np.int64),
                [part.build_args[0] for part in parts], first.build_args[1],
                [part.build_args[2] for part in parts], list(radii), first.build_args[5],
                [pts[a:b] for a, b in zip(row_start[:-1], row_start[1:], strict=True)],
                [part.flip for part in parts])
        else:
            setups = [map_setup(*part.build_args, lookups=pts[a:b], flip_axis=part.flip,
                                radii=radius)
                      for part, a, b, radius in zip(parts, row_start[:-1], row_start[1:],
                                                    radii, strict=True)]
            arrays = None
        joined = build_maps_together(setups, joined_lookups=(pts, row_start), ws=ws,
                                     joined=arrays)
        virtual, hidden = virtual_vertices_together(joined, pts, row_start, face, proj,
                                                    [part.screen for part in parts], ws)
        # seeds where the maps' virtual vertices land, each part's projected as it alone
        # projects them (in one call: a row's projection is its own among two or more
        # rows; a part's single row is projected alone); then every part's points refined
        # in one region
        seeds = screen_from_world(virtual, first.clip_from_world, camera.width,
                                  camera.height)[:, :2]
        for a in np.flatnonzero(np.diff(row_start) == 1):
            row = row_start[a]
            seeds[row] = screen_from_world(virtual[row:row + 1], first.clip_from_world,
                                           camera.width, camera.height)[0, :2]
        label = np.array([part.view.part for part in parts], np.int32)[row_part]
        refined, status = refine_parts(pts, seeds, first.view.owner, label, q, r,
                                       camera.eye, seeds_retry, reach=reach_m,
                                       out=(scratch(ws, "parts_refined", (m, 3), np.float64),
                                            scratch(ws, "parts_status", (m,), np.int8)))
    else:
        virtual = refined = np.empty((0, 3))
        hidden = np.empty(0, np.bool_)
        status = np.empty(0, np.int8)
    _scatter_parts(points, rows, row_start, virtual, hidden, refined, status, out, flags)
    return out, flags


def _locals(parts: list[ExplosionPart]) -> np.ndarray:
    """(P, F + 1) the parts' face tables (PartView.local) stacked: rows of the shape's own
    table (PartView.tables) where the parts are its parts p0, p0 + 1, .. (a frame's: not
    copied, 0.5 MB on the mask), else a stack of them."""
    whole = parts[0].view.tables
    p0 = parts[0].view.part
    if whole is not None and all(part.view.tables is whole and part.view.part == p0 + j
                                 for j, part in enumerate(parts)):
        return whole[p0:p0 + len(parts)]
    return np.stack([part.view.local for part in parts])


@njit(cache=True, parallel=True)
def _gather_parts(points, screen, retry, reach, rows, row_part, depth, triangle, local, pts,
                  proj, retry_out, reach_out, face):
    """Row m of the joined points (point rows[m] of part row_part[m]): its point, screen
    position, retry seed and reach (part p's rows of retry (P, N, 2) and reach (P, N)), and
    the part's face in front of it where it lies behind the reflector alone (PartView.
    faces_behind: depth, triangle, the part's local[p] face ids)."""
    for m in prange(rows.shape[0]):
        i = rows[m]
        p = row_part[m]
        for c in range(3):
            pts[m, c] = points[i, c]
            proj[m, c] = screen[i, c]
        retry_out[m, 0] = retry[p, i, 0]
        retry_out[m, 1] = retry[p, i, 1]
        reach_out[m] = reach[p, i]
        face[m] = face_behind(screen[i, 0], screen[i, 1], screen[i, 2], depth, triangle,
                              local[p])


@njit(cache=True, parallel=True)
def _scatter_parts(points, rows, row_start, virtual, hidden, refined, status, out, flags):
    """out[p] (N, 3) and flags[p] (N,): part p's answers, as ExplosionPart.__call__ makes
    them: the points themselves, flagged, where the part skips them; on its rows of the
    joined arrays the maps' answer (virtual, hidden), replaced by the refinement's where
    it found one (status not NONE), flagged unless exact, and where it ended at the
    part's boundary."""
    n = points.shape[0]
    for p in prange(out.shape[0]):
        for i in range(n):
            for c in range(3):
                out[p, i, c] = points[i, c]
            flags[p, i] = True
        for m in range(row_start[p], row_start[p + 1]):
            i = rows[m]
            st = status[m]
            src = refined if st != NONE else virtual
            for c in range(3):
                out[p, i, c] = src[m, c]
            flags[p, i] = (hidden[m] and st != EXACT) or st == BOUNDARY
