"""reflect: a batch renderer for mirror reflections."""

import os

# numba's default threading layer is GNU OpenMP, whose idle workers spin after each parallel
# loop. On a small machine that spinning takes the cores the next loop's threads, Embree's
# callers or the EXR writer need: a raytrace frame alternated with other work measured
# 69-77 ms spinning, 39-40 ms passive (teapot-box, 2 cores). Threads sleep when idle
# instead; results do not depend on it. Read by libgomp when numba first loads it (the first
# parallel kernel), so it is set here, before any; an explicit setting is kept.
os.environ.setdefault("OMP_WAIT_POLICY", "passive")

__version__ = "0.1.0"
