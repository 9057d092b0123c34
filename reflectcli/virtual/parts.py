"""All parts of a mesh reflector worked stage by stage: each stage (tile scan, explosion
maps, map lookups, refinement) done for every part before the next, the maps of all parts
built in one parallel region and all parts' points refined in one. Part by part, the
mask's 14 parts made each stage 14 short parallel regions one after another, the small
parts' ends leaving a thread idle; each part's answers are what it gives alone
(ExplosionPart.__call__)."""

from __future__ import annotations

import numpy as np

from .explosion import (
    build_maps_together,
    map_setup,
    virtual_vertices,
    virtual_vertices_together,
)
from .part import ExplosionPart, merge_refined
from .refine import refine_parts
from .screen import screen_from_world


def parts_vertices(parts: list[ExplosionPart], points: np.ndarray,
                   polygons: np.ndarray | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
    """[part(points, polygons) for part in parts] (virtual points (N, 3) world, flags (N,)),
    the parts being one reflector's in one view (their views' owner plane and ray grid
    shared)."""
    n = len(points)
    out = []
    todo_rows = []
    for part in parts:
        todo = retry = reach = None
        tiles = part.view.tiles
        if tiles is not None:
            reach, retry, todo = tiles.scan_needed(points, part.grid[0], part.grid[1],
                                                   polygons)
        rows = np.arange(n) if todo is None else np.flatnonzero(todo)
        todo_rows.append((rows, retry, reach))
        out.append((points.astype(np.float64), np.ones(n, bool)))
    busy = [p for p, (rows, _, _) in enumerate(todo_rows) if rows.size]
    if not busy:
        return out
    first = parts[busy[0]]
    camera = first.camera
    screen = first.view.points.of(points, first.clip_from_world, camera.width, camera.height)
    # per part: its points, their screen positions, the part's face in front of hidden ones
    work = {}
    for p in busy:
        part = parts[p]
        rows, retry, reach = todo_rows[p]
        pts = points.take(rows, axis=0)
        proj = screen.take(rows, axis=0)
        work[p] = (pts, proj, part.view.faces_behind(proj, part.depth),
                   None if retry is None else retry.take(rows, axis=0),
                   None if reach is None else reach.take(rows))
    # the maps of every part whose maps are not built whole, in one region
    build = [p for p in busy if parts[p].built is None]
    found = {}
    if build:
        joined = build_maps_together([map_setup(*parts[p].build_args, lookups=work[p][0],
                                                flip_axis=parts[p].flip) for p in build])
        # and their lookups, in one region too
        answers = virtual_vertices_together(
            joined, [work[p][0] for p in build], [work[p][2] for p in build],
            [work[p][1][:, :2] for p in build], [parts[p].screen for p in build],
            [parts[p].flip for p in build])
        found.update(zip(build, answers, strict=True))
    for p in busy:
        if p not in found:  # maps built whole before (ExplosionPart.maps)
            part = parts[p]
            pts, proj, face, _, _ = work[p]
            found[p] = virtual_vertices(part.built, pts, face, proj[:, :2].copy(),
                                        part.screen, part.flip)
    refining = [p for p in busy if parts[p].grid is not None]
    if refining:
        _refine_all(parts, refining, work, found)
    for p in busy:
        rows = todo_rows[p][0]
        virtual, flags = out[p]
        virtual[rows], flags[rows] = found[p]
    return out


def _refine_all(parts: list[ExplosionPart], refining: list[int], work: dict,
                found: dict) -> None:
    """The refinement of parts `refining` (their work: points, screen, faces, retry,
    reach; found: their map answers, replaced by the refined ones) in one call when they
    share an owner plane and ray grid (one reflector's view), else part by part."""
    first = parts[refining[0]]
    shared = all(parts[p].view.owner is first.view.owner and parts[p].grid is first.grid
                 for p in refining)
    groups = [refining] if shared else [[p] for p in refining]
    for group in groups:
        part = parts[group[0]]
        camera = part.camera
        pts = np.concatenate([work[p][0] for p in group])
        # seeds per part, as a part alone projects them (the same rows: the same numbers)
        seeds = np.concatenate([screen_from_world(found[p][0], part.clip_from_world,
                                                  camera.width, camera.height)[:, :2]
                                for p in group])
        label = np.concatenate([np.full(len(work[p][0]), parts[p].view.part, np.int32)
                                for p in group])
        retry = reach = None
        if any(work[p][3] is not None for p in group):
            retry = np.concatenate([np.full((len(work[p][0]), 2), np.nan) if work[p][3] is None
                                    else work[p][3] for p in group])
        if any(work[p][4] is not None for p in group):
            reach = np.concatenate([np.ones(len(work[p][0]), bool) if work[p][4] is None
                                    else work[p][4] for p in group])
        refined, status = refine_parts(pts, seeds, part.view.owner, label, part.grid[0],
                                       part.grid[1], camera.eye, retry, reach=reach)
        k = 0
        for p in group:
            m = len(work[p][0])
            virtual, flags = found[p]
            found[p] = merge_refined(virtual, flags, refined[k:k + m], status[k:k + m])
            k += m
