"""A frame's rays, traced and shaded in one parallel loop over segments of rays.

The rays of a frame are cut into segments: a few image rows of primary rays each. A
segment is one work item, handed to whichever thread is free, and goes through every wave
(the primary rays, then each mirror bounce of the rays its own rays reflected) and every step
of a wave while its arrays are still in the core's cache: (primary rays of its rows,)
Embree on the objects and on the mesh mirrors (`embree.intersect_range`), the analytic
mirrors (`analytic.intersect_range`), hit resolution (`resolve.resolve_range`), whose
reflected rays it writes, in order, to the start of its part of the other ray buffer. No
wave waits for another segment's, so a frame is one parallel region. A pixel's rays all
belong to one segment and every ray writes only its own outputs, so the bytes do not depend
on which thread traced what.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..parallel import claim, counter
from .analytic import intersect_range as analytic_range
from .analytic import intersect_rows as analytic_rows
from .embree import intersect_range as embree_range
from .embree import packet_buffer
from .rays import rows_of_rays
from .resolve import resolve_range


@njit(cache=True, parallel=True)
def trace_segments(seg_len, counts, rows_per_seg, cam, buffers, tfars, objects, mirrors,
                   analytic, surfaces, bounces, max_depth, hits, color, near, reflected_hit,
                   traced, threads, per_worker):
    """Waves bounces[0] .. bounces[1] (0: the primary rays) of segments k = 0 ..
    len(counts) - 1, each segment through all of them in turn: wave b traces counts[k] rays
    of ray buffer buffers[b % 2] (origins, dirs, weights, slots) and emits the reflected rays
    into buffers[(b + 1) % 2] (while b < max_depth). counts[k] becomes the number the last
    wave emitted; traced[k, b] is the number wave b traced. `threads`: numba's thread count.

    Where a segment's rays live: with `per_worker` false, rays k * seg_len .. of the ray
    buffers and hit arrays, which span the frame, and slots index the frame's outputs. With
    `per_worker` true, the ray buffers and hit arrays hold `threads` * seg_len rows and the
    worker w tracing segment k uses rows w * seg_len .. (w + 1) * seg_len - 1 only, its slots
    counted from the segment's first output row k * seg_len: a frame then touches its
    outputs and a scratch the size of a segment per thread, which stays in the cache
    (needs bounces[0] == 0 and rays made here).

    `rows_per_seg` > 0: the primary wave makes its rays here, image rows k * rows_per_seg
    onward of `cam` (rays.camera_rays) (0: they are given). `tfars`: the primary rays' and
    the reflected rays' tfar. `objects`, `mirrors`: (Embree scene handle, hits given, t,
    primitive, u, v): a nonzero handle is traced here; with none, the hit arrays are either
    given (the embreex fallback fills them first, one wave a call) or all misses.
    `analytic`: (any analytic mirror, kind, params, quad edges, screen boxes of the primary
    rays' camera (analytic.screen_boxes), t, index). `surfaces`:
    resolve_range's scene arrays, from the objects' corners to the background. `hits`:
    ((depth, surface ids) of the primary wave: t + near, inf on a miss, at the frame's rows;
    (t, surface) of the others) per ray. Writes color (rows of the rays' slots); the first
    bounce marks reflected_hit[slot] of its rays that hit anything."""
    rays_a, rays_b = buffers  # (tuples of tuples do not enter the parallel loop)
    first_hits, hits = hits
    # one item per thread, each claiming the next segment until none is left (parallel.py)
    claimed = counter()
    whole = 1 << 62  # a view's length reaching the end of any array (slices clamp)
    for w in prange(threads):
        while True:
            k = claim(claimed)
            if k >= counts.shape[0]:
                break
            # one call of the segment (a function of its own, not inlined: in the parallel
            # loop's body the whole tracer compiled 154 s, as a call 56 s; a call a segment
            # costs nothing measurable): views of the scratch rows and output rows this
            # segment uses, from which its rays start at lo
            if per_worker:  # scratch rows w * seg_len .., outputs from row k * seg_len
                lo, s0, sn, o0, on = 0, w * seg_len, seg_len, k * seg_len, seg_len
            else:  # the frame-wide arrays, rays from row k * seg_len
                lo, s0, sn, o0, on = k * seg_len, 0, whole, 0, whole
            _segment(k, lo, seg_len, counts, rows_per_seg, cam, _rows4(rays_a, s0, sn),
                     _rows4(rays_b, s0, sn), tfars, _rows_hits(objects, s0, sn),
                     _rows_hits(mirrors, s0, sn), _rows_analytic(analytic, s0, sn), surfaces,
                     bounces, max_depth, _rows2(first_hits, o0, on), _rows2(hits, s0, sn),
                     color[o0:o0 + on], near, reflected_hit[o0:o0 + on], traced)


@njit(cache=True, inline="always")
def _rows2(arrays, start, n):
    """Rows start .. start + n - 1 of each of two arrays (views)."""
    a, b = arrays
    return a[start:start + n], b[start:start + n]


@njit(cache=True, inline="always")
def _rows4(arrays, start, n):
    """Rows start .. start + n - 1 of each of four arrays (views)."""
    a, b, c, d = arrays
    return a[start:start + n], b[start:start + n], c[start:start + n], d[start:start + n]


@njit(cache=True, inline="always")
def _rows_hits(side, start, n):
    """An (Embree handle, given, t, primitive, u, v) side with its hit arrays' rows start ..
    start + n - 1."""
    scene, given, t, p, u, v = side
    t, p, u, v = _rows4((t, p, u, v), start, n)
    return scene, given, t, p, u, v


@njit(cache=True, inline="always")
def _rows_analytic(analytic, start, n):
    """The analytic side (any, kind, params, edges, boxes, t, index) with its hit arrays' rows
    start .. start + n - 1."""
    any_analytic, kind, params, edges, boxes, t, index = analytic
    t, index = _rows2((t, index), start, n)
    return any_analytic, kind, params, edges, boxes, t, index


@njit(cache=True)
def _segment(k, lo, seg_len, counts, rows_per_seg, cam, rays_a, rays_b, tfars, objects,
             mirrors, analytic, surfaces, bounces, max_depth, first_hits, hits, color, near,
             reflected_hit, traced):
    """Segment k through waves bounces[0] .. bounces[1], its rays from row lo of the ray
    buffers and hit arrays on."""
    count = counts[k]
    per_row = cam[5] * cam[7] * cam[7]  # rays an image row
    for bounce in range(bounces[0], bounces[1] + 1):
        traced[k, bounce] = count
        if count == 0:
            break
        even = bounce % 2 == 0
        count = _wave(lo, lo + count, k * seg_len // per_row, rows_per_seg, cam,
                      rays_a if even else rays_b, tfars[min(bounce, 1):min(bounce, 1) + 1],
                      objects, mirrors, analytic, surfaces, bounce < max_depth, bounce,
                      first_hits if bounce == 0 else hits, color, rays_b if even else rays_a,
                      near, reflected_hit)
    counts[k] = count


@njit(cache=True, inline="always")
def _wave(lo, hi, j0, rows_per_seg, cam, rays, tfar, objects, mirrors, analytic, surfaces,
          follow, bounce, hits, color, out_rays, near, reflected_hit):
    """Wave `bounce` of a segment: rays lo .. hi - 1 (on the primary wave the rays of image
    rows j0 onward, made here from row lo on when rows_per_seg > 0); returns how many it
    emitted."""
    origins, dirs, weight, slot = rays
    obj_scene, obj_given, t_o, p_o, u_o, v_o = objects
    mir_scene, mir_given, t_m, p_m, u_m, v_m = mirrors
    any_analytic, kind, params, edges, boxes, t_a, k_a = analytic
    hit_t, hit_surface = hits
    first = bounce == 0
    per_row = cam[5] * cam[7] * cam[7]
    if first and rows_per_seg > 0:
        rows_of_rays(j0, min(cam[6], j0 + rows_per_seg), j0 * per_row - lo, cam, origins, dirs)
    if obj_scene != 0 or mir_scene != 0:
        buf, off = packet_buffer()
        if obj_scene != 0:
            embree_range(obj_scene, origins, dirs, tfar, lo, hi, t_o, p_o, u_o, v_o, buf, off)
        if mir_scene != 0:
            embree_range(mir_scene, origins, dirs, tfar, lo, hi, t_m, p_m, u_m, v_m, buf, off)
    if obj_scene == 0 and not obj_given:
        _misses(lo, hi, t_o, p_o)
    if mir_scene == 0 and not mir_given:
        _misses(lo, hi, t_m, p_m)
    if any_analytic and first:  # only rays of pixels in a mirror's screen box can meet it
        analytic_rows(lo, hi, j0, per_row, cam[7] * cam[7], boxes, origins, dirs, tfar, kind,
                      params, edges, 0.0, t_a, k_a)
    elif any_analytic:
        analytic_range(lo, hi, origins, dirs, tfar, kind, params, edges, 0.0, t_a, k_a)
    else:
        _misses(lo, hi, t_a, k_a)
    # `first` as a constant in each copy: its branches per ray fold away
    if first:
        emitted = resolve_range(lo, hi, rays, (t_o, p_o, u_o, v_o), (t_m, p_m, u_m, v_m),
                                (t_a, k_a), surfaces, follow, color, hits, out_rays, lo, True)
    else:
        emitted = resolve_range(lo, hi, rays, (t_o, p_o, u_o, v_o), (t_m, p_m, u_m, v_m),
                                (t_a, k_a), surfaces, follow, color, hits, out_rays, lo, False)
    # (indices unsigned, as in resolve.resolve_range)
    if first:  # depth: t + near (a miss's inf stays inf)
        for n in range(lo, hi):
            hit_t[np.uint64(n)] += near
    elif bounce == 1:
        for n in range(lo, hi):
            i = np.uint64(n)
            if hit_surface[i] >= 0:
                reflected_hit[np.uint64(slot[i])] = 1.0
    return emitted


@njit(cache=True, inline="always")
def _misses(lo, hi, t, index):
    """No hit for rays lo .. hi - 1: t inf, index -1."""
    for i in range(lo, hi):
        t[i] = np.inf
        index[i] = -1
