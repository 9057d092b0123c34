"""Forward warping of zexel maps into a mirror's pixels (numba), McMillan's 3D warp.

Each zexel at map pixel (u, v) with eye-space depth z has generalized disparity
delta = 1 / z (0 for empty zexels: points at infinity, which still warp correctly as
directions). Its homogeneous map-eye point is D (u, v, 1, delta) with D the map camera's
pixel-to-ray matrix; the world point is V_map^-1 of that, its mirror image R of that, and
its place on the screen P V of that. One 4x4 W = P V R V_map^-1 D per map and frame:
clip = W (u, v, 1, delta), which is equation 3 of the paper written projectively:
x_o ~ delta P_o^-1 (c_i - c_o) + P_o^-1 P_i x_i. The paper's equation 4 disparity,
1 - z_window (far - near) / far, equals near / z for a plain perspective depth buffer: ours up
to the constant `near`, which the projective form absorbs; storing eye-space depth keeps it
exact for the oblique capture projection, whose window z is not that of a plain one.

The package, one idea a module:
    projection   the matrices and the float32 projection of a map (row by row, vectorized)
    visibility   the visibility rule's constant (and the rule, in its docstring)
    order        the zexels' traversal order: row-major, or McMillan's occlusion-compatible
    pixels       the one-pixel splat (z-buffer or ordered), payload rows written as it goes
    spreading    wider fixed splats as a spread of the one-pixel result
    squares      adaptive splats and ordered wide ones: each zexel over its square
    payload      copying zexels' rows (colour, triangle) to pixels; the gather pass
    fill         dprm's fill of holes and blend into the frame
    buffers      the arrays kept across frames
    api          warp_maps / warp_depths: which splat runs, over which region
"""

from .api import warp_depths, warp_maps
from .buffers import WarpBuffers, stencil_box
from .fill import fill_blend
from .order import ordered_runs, raster_runs
from .payload import gather_colors
from .pixels import splat_pixels
from .projection import (
    Projection,
    pixel_to_eye,
    project_map,
    screen_matrix,
    warp_matrix,
)
from .spreading import spread
from .squares import splat, splat_radii
from .visibility import SAME_SURFACE

__all__ = [
    "SAME_SURFACE", "Projection", "WarpBuffers", "fill_blend", "gather_colors", "ordered_runs",
    "pixel_to_eye", "project_map", "raster_runs", "screen_matrix", "splat", "splat_pixels",
    "splat_radii", "spread", "stencil_box", "warp_depths", "warp_maps", "warp_matrix",
]
