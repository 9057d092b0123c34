"""reflect: a batch renderer for mirror reflections."""

import os

# numba's threading layer is GNU OpenMP. Its idle workers spin-wait by default (about 5 ms
# after each parallel loop on this machine kind), which takes the cores the next frame's
# threads, Embree's callers or the EXR writer need: a raytrace frame alternated with other
# work measured 69-77 ms spinning, 39-40 ms passive (teapot-box, 2 cores). So workers sleep
# when idle (passive), but first spin briefly (GOMP_SPINCOUNT 50,000: about 0.7 ms of a
# core): waking a worker that already sleeps costs about 50 us a parallel loop on a 2-vCPU
# guest (a 26 us two-thread loop took 78 us after a 0.2 ms pause, 28 us when the worker
# still spun), and a virtual frame on the mask runs some 25 loops with pauses of Python
# between them of 0.3 ms at most. Results do not depend on either. Read by libgomp when
# numba first loads it (the first parallel kernel), so they are set here, before any; an
# explicit setting of either is kept (libgomp lets GOMP_SPINCOUNT override the policy).
if "OMP_WAIT_POLICY" not in os.environ:
    os.environ["OMP_WAIT_POLICY"] = "passive"
    os.environ.setdefault("GOMP_SPINCOUNT", "50000")

__version__ = "0.1.0"
