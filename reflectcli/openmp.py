"""How numba's OpenMP workers wait between parallel loops: read by libgomp once, when numba
first loads it (the first parallel kernel), so set before any.

libgomp's idle workers spin-wait by default (about 5 ms after each parallel loop on this
machine kind), which takes the cores the next frame's threads, Embree's callers or the EXR
writer need: a raytrace frame alternated with other work measured 69-77 ms spinning, 39-40
ms passive (teapot-box, 2 cores). Fully passive workers (sleeping at once) cost a wake-up
per parallel loop instead, about 50 us on a 2-vCPU guest (a 26 us two-thread loop took 78
us after a 0.2 ms pause of Python, 28 us when the worker still spun), and a virtual frame
on the mask runs some 25 loops with pauses of at most 0.3 ms between them. So workers
spin briefly (`SPIN` rounds: about 0.7 ms of a core), then sleep. Processes that share the
cores with others of their kind (`reflect bench --workers`, the test suite's workers) spin
none (`no_spin`): there a spinning worker holds a core another process needs. Results never
depend on any of it."""

from __future__ import annotations

import os

SPIN = "50000"  # GOMP_SPINCOUNT: rounds a worker spins before it sleeps
_MARK = "REFLECT_OPENMP_DEFAULT"  # exported with the default, so child processes know it

defaulted = False  # True when the waiting is reflect's default (not the user's setting)


def default_waiting() -> None:
    """Passive workers after `SPIN` rounds of spinning, unless the environment says how
    they wait (OMP_WAIT_POLICY or GOMP_SPINCOUNT: an explicit setting is kept; one this
    function made in a parent process, marked, counts as the default)."""
    global defaulted
    if os.environ.get(_MARK) == "1":
        defaulted = True
        return
    if "OMP_WAIT_POLICY" in os.environ or "GOMP_SPINCOUNT" in os.environ:
        return
    os.environ["OMP_WAIT_POLICY"] = "passive"
    os.environ["GOMP_SPINCOUNT"] = SPIN
    os.environ[_MARK] = "1"
    defaulted = True


def no_spin() -> None:
    """Workers sleep as soon as they are idle: for a process sharing the cores with others
    of its kind. Call before the first parallel kernel (a spawned child's initializer)."""
    os.environ["OMP_WAIT_POLICY"] = "passive"
    os.environ["GOMP_SPINCOUNT"] = "0"
