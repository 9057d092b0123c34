"""A mesh reflector's parts set up for a frame all at once: their ray foci's normal
equations, their extents and screen positions (ExplosionPart), and their explosion maps'
per-vertex and per-face arrays (map_setup), each stage one kernel over the parts' meshes
joined (JoinedParts, made once per shape) instead of a kernel call and a dozen numpy calls
a part. On the mask (14 parts) the part-by-part set-up took about 1.2 ms of a frame at 1
thread, all of it serial at 2. Each part's numbers are those of its own calls
(`explosion.ray_foci`, `ExplosionPart`, `explosion.map_setup`): the kernels run the same
per-part kernels on the part's rows.

    world: every vertex, focus and centre here; screen: pixels, y down (screen.py)
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .explosion import MapSetup, _focus_sums, _map_frames, _setup_arrays, foci_from_sums
from .part import _extent, _lookup_axis
from .screen import screen_from_world
from .shape import JoinedParts, starts_of


def _every_part(joined: JoinedParts, chosen: np.ndarray) -> bool:
    """Whether `chosen` is every part of `joined`, in order (their joined arrays serve as
    they are)."""
    return len(chosen) == len(joined.vstart) - 1 and bool((chosen == np.arange(len(chosen))).all())


def parts_foci(joined: JoinedParts, chosen: np.ndarray, meshes: list,
               eye: np.ndarray) -> list[np.ndarray]:
    """explosion.ray_foci of the chosen parts (`meshes`: theirs, for the vertex-mean
    fallback): their normal equations in one kernel call."""
    eye = np.asarray(eye, np.float64)
    a = np.empty((len(chosen), 3, 3))
    b = np.empty((len(chosen), 3))
    front = np.empty(len(chosen), np.int64)
    _focus_sums_parts(joined.vertices, joined.normals, joined.vstart, chosen, eye, a, b,
                      front)
    return foci_from_sums(a, b, front, meshes)


@njit(cache=True)
def _focus_sums_parts(v, n, vstart, chosen, eye, a, b, front):
    """explosion._focus_sums of each chosen part (row j: part chosen[j])."""
    for j in range(chosen.shape[0]):
        p = chosen[j]
        aj, bj, count = _focus_sums(v[vstart[p]:vstart[p + 1]], n[vstart[p]:vstart[p + 1]],
                                    eye)
        a[j] = aj
        b[j] = bj
        front[j] = count


def parts_extents(joined: JoinedParts, chosen: np.ndarray, centres: np.ndarray,
                  concave: np.ndarray, scene_points: np.ndarray, eye: np.ndarray,
                  clip_from_world: np.ndarray, width: int, height: int) -> list[tuple]:
    """Per chosen part, what ExplosionPart works out from its vertices (its `extent`):
    (bound, far, front (V,) bool, screen (V, 2), flip (3,)) as part._extent,
    screen_from_world and ExplosionPart's lookup axis (`concave` parts: their front
    normals' mean, made unit) give them for the part alone."""
    count = len(chosen)
    sizes = joined.vstart[chosen + 1] - joined.vstart[chosen]
    out_start = starts_of(sizes)
    front = np.empty(int(out_start[-1]), np.bool_)
    bound = np.empty(count)
    far = np.empty(count)
    flips = np.empty((count, 3))
    _extent_parts(joined.vertices, joined.normals, joined.vstart, chosen,
                  np.ascontiguousarray(centres, np.float64),
                  np.asarray(concave, np.bool_),
                  np.ascontiguousarray(scene_points, np.float64),
                  np.asarray(eye, np.float64), out_start, front, bound, far, flips)
    if _every_part(joined, chosen) and (sizes > 1).all():
        # a row's projection is its own among two or more rows (screen._screen_rows)
        screen = screen_from_world(joined.vertices, clip_from_world, width, height)
        screens = [screen[out_start[j]:out_start[j + 1], :2] for j in range(count)]
    else:
        screens = [screen_from_world(joined.vertices[joined.vstart[p]:joined.vstart[p + 1]],
                                     clip_from_world, width, height)[:, :2] for p in chosen]
    return [(float(bound[j]), float(far[j]), front[out_start[j]:out_start[j + 1]],
             screens[j], flips[j]) for j in range(count)]


@njit(cache=True)
def _extent_parts(v, n, vstart, chosen, centres, concave, scene_points, eye, out_start,
                  front, bound, far, flips):
    """part._extent of each chosen part (row j: part chosen[j], centre centres[j]); its
    front rows out_start[j] .. of `front`; flips[j] its lookup axis (part._lookup_axis) if
    the part is concave, else 0."""
    for j in range(chosen.shape[0]):
        p = chosen[j]
        a, b = vstart[p], vstart[p + 1]
        faces_eye = front[out_start[j]:out_start[j + 1]]
        bound[j], far[j] = _extent(v[a:b], n[a:b], centres[j], scene_points, eye, faces_eye)
        flips[j, 0] = flips[j, 1] = flips[j, 2] = 0.0
        if concave[j]:
            _lookup_axis(n[a:b], faces_eye, flips[j])


def parts_map_setups(joined: JoinedParts, chosen: np.ndarray, meshes: list, eye: np.ndarray,
                     centres: list[np.ndarray], radii: list[np.ndarray], res: int,
                     lookups: list[np.ndarray | None], flips: list[np.ndarray]
                     ) -> tuple[list[MapSetup], tuple]:
    """explosion.map_setup of each chosen part (`meshes`, `centres`, `radii`, `lookups`,
    `flips`: theirs), and the arrays build_maps_together joins from them, already joined
    (v, fixed normals, used, faces, drawn, extensions): every part's in one kernel call;
    each MapSetup's arrays are views of the joined ones."""
    eye = np.asarray(eye, np.float64)
    count = len(chosen)
    vsize = joined.vstart[chosen + 1] - joined.vstart[chosen]
    fsize = joined.fstart[chosen + 1] - joined.fstart[chosen]
    bsize = joined.bstart[chosen + 1] - joined.bstart[chosen]
    nv = int(vsize.sum())
    fixed = np.empty((nv, 3))
    front = np.empty(nv, np.bool_)
    used = np.empty(nv, np.bool_)
    drawn = np.empty(int(fsize.sum()), np.int64)
    extensions = np.empty((int(fsize.sum() + bsize.sum()), 3), np.int64)
    counts = np.empty((count, 2), np.int64)
    _setup_arrays_parts(joined.vertices, joined.normals, joined.vstart, joined.faces,
                        joined.fstart, joined.boundary, joined.bstart, chosen, eye, fixed,
                        front, used, drawn, extensions, counts)
    v0, d0, e0 = starts_of(vsize), starts_of(counts[:, 0]), starts_of(counts[:, 1])
    frames = np.empty((count, 3, 3))
    _map_frames(np.array(centres, np.float64).reshape(-1, 3), eye, frames)
    setups = []
    s = res - 2.0
    for j in range(count):
        looked = None if lookups[j] is None else np.ascontiguousarray(lookups[j], np.float64)
        flip = np.zeros(3) if flips[j] is None else np.asarray(flips[j], np.float64)
        setups.append(MapSetup(meshes[j], eye, fixed[v0[j]:v0[j + 1]],
                               front[v0[j]:v0[j + 1]], used[v0[j]:v0[j + 1]],
                               drawn[d0[j]:d0[j + 1]], extensions[e0[j]:e0[j + 1]],
                               frames[j], np.asarray(centres[j], np.float64),
                               radii[j], res, s, looked, flip))
    everyone = _every_part(joined, chosen)
    v = joined.vertices if everyone else np.concatenate([m.vertices for m in meshes])
    faces = joined.faces if everyone else np.concatenate([m.faces for m in meshes])
    return setups, (v, fixed, used, faces, drawn[:d0[-1]], extensions[:e0[-1]])


@njit(cache=True)
def _setup_arrays_parts(v, n, vstart, faces, fstart, boundary, bstart, chosen, eye, fixed,
                        front, used, drawn, extensions, counts):
    """explosion._setup_arrays of each chosen part, its rows written one part after
    another: vertex rows in part order, drawn faces and extensions appended (counts[j]:
    part j's numbers of them)."""
    ov = 0
    od = 0
    oe = 0
    for j in range(chosen.shape[0]):
        p = chosen[j]
        a, b = vstart[p], vstart[p + 1]
        fx, fr, us, dr, ex = _setup_arrays(v[a:b], n[a:b], faces[fstart[p]:fstart[p + 1]],
                                           boundary[bstart[p]:bstart[p + 1]], eye)
        fixed[ov:ov + b - a] = fx
        front[ov:ov + b - a] = fr
        used[ov:ov + b - a] = us
        drawn[od:od + dr.shape[0]] = dr
        extensions[oe:oe + ex.shape[0]] = ex
        counts[j, 0] = dr.shape[0]
        counts[j, 1] = ex.shape[0]
        ov += b - a
        od += dr.shape[0]
        oe += ex.shape[0]
