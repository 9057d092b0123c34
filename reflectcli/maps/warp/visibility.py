"""The warp's visibility rule (its constant; the kernels apply it where they write).

z-buffer mode keeps, per pixel, a zexel of the surface nearest the eye, and of that
surface's zexels (eye depth within SAME_SURFACE) the one that lands nearest the pixel's
center (ties to the lower id); where a surface's zexels in one pixel span more than
SAME_SURFACE in depth (grazing views), which of them is kept can depend on their order.
Keeping simply the nearest depth would pick, on a slanted surface, the zexel on the near
edge of the pixel, a bias that grows as maps get denser; the center rule makes a denser
map converge on the point sample at the center.
Ordered mode paints each map in McMillan's occlusion-compatible order (later overwrite),
z-testing only against other maps.
"""

SAME_SURFACE = 0.01  # relative eye-depth difference within which two zexels are one surface
