"""Z-buffer rasterization of triangles into triangle-id, depth and barycentric buffers.

Pipeline per triangle: world -> clip (one 4x4), clipping in homogeneous clip space against
the near and far planes, any extra planes and a guard band around the screen
(Sutherland-Hodgman), perspective divide to NDC, viewport to screen (x right, y down, pixel
centers at +0.5), then snapped to a fixed-point grid of 2^-S pixel (S = `_subpixel_bits`:
15 bits at 8192 pixels, 18 at 640x480, more on smaller screens).

Coverage is exact: the three edge functions of the snapped corners are int64 (no rounding),
stepped along each row, and a pixel center on an edge belongs to exactly one of the two
triangles sharing it (the top-left rule: an edge owns its points when its inward normal
points right, or straight down the screen). Shared edges leave neither cracks nor double
hits. The z-buffer holds the key 1/w (affine in screen space: a plane per triangle from its
bounding-box corner, float64, stored as float32; a mirror's divided by MIRROR_TIE, so mirrors
win ties); nearer is a greater key, and an equal key goes to the lower triangle index.
Barycentrics are not written per fragment: they are recovered from the visible triangle's
clip-space corners and the pixel center's NDC (`recover_barycentrics`: perspective-correct by
construction, the same for clipped triangles), by the shading kernels as they shade, or for
the whole buffer on first use of `RasterBuffers.b1` / `b2`. Eye depth is 1 / key.

Sort-last: triangles go in runs of _CHUNK, claimed by whichever thread is free
(parallel.py), each drawing into its own buffers (the stencil's box, plus a spare row and
_NARROW - 1 spare columns: `thread_buffers`), merged per pixel at the end. The depth test and
the merge both pick the greatest key, then the lowest index, and every key depends only on
the triangle and the pixel, so the bytes are the same for any thread count and any order
the runs are drawn in. Within a run, the per-corner work (clip space, classification,
projection, snapping, a cheap test of facing and covered centres) is done for all its
triangles at once in vectorised loops, and the full setup only for those the test lists
(`_run_setup`); then each is filled (`_fill_listed`: a box of at most 2 x 2 centres
directly, `_quad`, a bigger one row by row, `_rows`). With a workspace, a run whose world box
misses the view, an extra plane or the stencil's box is skipped whole (`_box_misses`).

The package, one idea a module:
    constants     culling modes, triangle flags and statuses, run and block sizes
    fixed         the fixed-point screen grid (subpixel bits, snapping)
    clip          clipping in clip space; skipping a run by its world box
    setup         triangle setup, one triangle and a whole run
    rows          the row walk with the depth test; one triangle's fill
    draw          the parallel draw into per-thread buffers, clipped fans
    resolve       merging the threads' buffers; keys to eye depths
    stencil       the stencil's bounding box
    barycentrics  barycentrics recovered from clip-space corners
    buffers       RasterBuffers and RasterWorkspace
    api           rasterize
"""

from ...camera import standard_planes
from .api import rasterize
from .barycentrics import barycentrics_at, clip_corners, recover_barycentrics
from .buffers import RasterBuffers, RasterWorkspace
from .clip import screen_from_ndc
from .constants import (
    CULL_BACK,
    CULL_FRONT,
    CULL_NONE,
    FLAG_CULL_BACK,
    FLAG_CULL_FRONT,
    FLAG_MIRROR,
    FLAG_SKIP,
)

__all__ = [
    "CULL_BACK", "CULL_FRONT", "CULL_NONE", "FLAG_CULL_BACK", "FLAG_CULL_FRONT", "FLAG_MIRROR",
    "FLAG_SKIP",
    "RasterBuffers",
    "RasterWorkspace", "barycentrics_at", "clip_corners", "rasterize", "recover_barycentrics",
    "screen_from_ndc", "standard_planes",
]
