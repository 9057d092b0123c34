"""The rasterizer's constants: culling modes, triangle flags and statuses, plane limits, and
the sizes of its runs and blocks."""

_MAX_PLANES = 8
_GUARD_PLANES = 4
_MAX_POLY = 3 + _MAX_PLANES + _GUARD_PLANES

# culling modes (bits: a triangle flagged FLAG_CULL_BACK in a CULL_FRONT pass culls both)
CULL_NONE, CULL_BACK, CULL_FRONT = 0, 1, 2

# per-triangle flags: a mirror's (wins depth ties), left out of the pass, and dropped when
# its screen winding is clockwise (FLAG_CULL_BACK) or counter-clockwise (FLAG_CULL_FRONT),
# besides what the pass's culling mode drops (a closed piece seen from outside: its back
# faces lie behind its front faces, see raster/closed.py; a reflection pass flips the
# winding). The culling flags are the culling modes' bits shifted by _CULL_SHIFT.
FLAG_MIRROR, FLAG_SKIP, FLAG_CULL_BACK, FLAG_CULL_FRONT = 1, 2, 4, 8
_CULL_SHIFT = 2

# triangle status after setup
_CULLED, _SIMPLE, _CLIPPED = 0, 1, 2

_CHUNK = 256  # triangles per parallel task (and per box of chunk_bounds)
# A plain row is walked in whole blocks of _BLOCK pixels, those past the triangle's box
# masked (rewritten unchanged): the compiler's vectorised loop then never falls to its
# scalar remainder, whose branches on the row's length (1 to 4 pixels on most triangles of
# a detailed mesh) mispredict. 202k triangles, 1 thread: culled 1.03 -> 0.95x the anchor,
# unculled 1.41 -> 1.26x (8 was slower than 4)
_BLOCK = 4
# A plain draw's boxes at most _NARROW pixels wide are walked _BLOCK or _NARROW pixels a row,
# a constant, unrolled (`_narrow`); the buffers have _NARROW - 1 columns to spare
_NARROW = 8
