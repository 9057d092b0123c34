"""One wave of rays, traced and shaded in one parallel loop over segments of rays.

The rays of a frame are cut into segments: a few image rows of primary rays each. A
segment is one work item, handed to whichever thread is free, and goes through every step
while its arrays are still in the core's cache: (primary rays of its rows,) Embree on the
objects and on the mesh mirrors (`embree.intersect_range`), the analytic mirrors
(`analytic.intersect_range`), hit resolution (`resolve.resolve_range`), whose reflected rays
it writes, in order, to the start of the same segment of the next wave's arrays. The next
wave has the same segments, each as long as the rays its segment emitted (`counts`). So a
wave is one parallel region, and a frame has one per bounce. Every ray writes only its own
outputs, so the bytes do not depend on which thread traced what.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .analytic import intersect_range as analytic_range
from .embree import intersect_range as embree_range
from .embree import packet_buffer
from .rays import rows_of_rays
from .resolve import resolve_range


@njit(cache=True, parallel=True)
def trace_wave(seg_len, counts, rows_per_seg, cam, rays, tfar, objects, mirrors, analytic,
               surfaces, follow, bounce, hits, color, out_rays, out_counts, near,
               reflected_hit):
    """Wave `bounce` (0: primary) over segments k = 0 .. len(counts) - 1: rays
    k * seg_len .. k * seg_len + counts[k] - 1 of `rays` (origins, dirs, weights, slots).

    `rows_per_seg` > 0: the primary wave makes its rays here, image rows
    k * rows_per_seg onward of `cam` (rays.camera_rays), into the rays' arrays (0: they are
    given). `objects`, `mirrors`: (Embree scene handle, hits given, t, primitive, u, v):
    a nonzero handle is traced here; with none, the hit arrays are either given (the embreex
    fallback fills them first) or all misses. `analytic`: (any analytic mirror, kind,
    params, quad edges, t, index). `surfaces`: resolve_range's scene arrays, from the
    objects' corners to the background. `hits`: (hit_t, hit_surface) per ray; the primary
    wave's are the frame's depth (t + near, inf on a miss) and surface ids.

    Writes color (rows of the rays' slots), the reflected rays to out_rays with their number
    per segment in out_counts; the first bounce marks reflected_hit[slot] of its rays that
    hit anything."""
    origins, dirs, weight, slot = rays
    obj_scene, obj_given, t_o, p_o, u_o, v_o = objects
    mir_scene, mir_given, t_m, p_m, u_m, v_m = mirrors
    any_analytic, kind, params, edges, t_a, k_a = analytic
    hit_t, hit_surface = hits
    first = bounce == 0
    height = cam[6]
    for k in prange(counts.shape[0]):
        lo = k * seg_len
        hi = lo + counts[k]
        if hi == lo:
            out_counts[k] = 0
            continue
        if rows_per_seg > 0:
            j0 = k * rows_per_seg
            rows_of_rays(j0, min(height, j0 + rows_per_seg), cam, origins, dirs)
        if obj_scene != 0 or mir_scene != 0:
            buf, off = packet_buffer()
            if obj_scene != 0:
                embree_range(obj_scene, origins, dirs, tfar, lo, hi, t_o, p_o, u_o, v_o, buf,
                             off)
            if mir_scene != 0:
                embree_range(mir_scene, origins, dirs, tfar, lo, hi, t_m, p_m, u_m, v_m, buf,
                             off)
        if obj_scene == 0 and not obj_given:
            _misses(lo, hi, t_o, p_o)
        if mir_scene == 0 and not mir_given:
            _misses(lo, hi, t_m, p_m)
        if any_analytic:
            analytic_range(lo, hi, origins, dirs, tfar, kind, params, edges, 0.0, t_a, k_a)
        else:
            _misses(lo, hi, t_a, k_a)
        out_counts[k] = resolve_range(
            lo, hi, rays, (t_o, p_o, u_o, v_o), (t_m, p_m, u_m, v_m), (t_a, k_a), surfaces,
            follow, color, hits, out_rays, lo, first)
        if first:  # depth: t + near (a miss's inf stays inf)
            for i in range(lo, hi):
                hit_t[i] += near
        elif bounce == 1:
            for i in range(lo, hi):
                if hit_surface[i] >= 0:
                    reflected_hit[slot[i]] = 1.0


@njit(cache=True, inline="always")
def _misses(lo, hi, t, index):
    """No hit for rays lo .. hi - 1: t inf, index -1."""
    for i in range(lo, hi):
        t[i] = np.inf
        index[i] = -1
