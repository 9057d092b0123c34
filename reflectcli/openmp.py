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
# exported with the values this module set ("policy/spin count"), so that a child process
# knows them for reflect's default while its environment still holds just those
_MARK = "REFLECT_OPENMP_DEFAULT"

defaulted = False  # True when the waiting is reflect's default (not the user's setting)


def _held() -> str:
    return f"{os.environ.get('OMP_WAIT_POLICY')}/{os.environ.get('GOMP_SPINCOUNT')}"


def default_waiting() -> None:
    """Passive workers after `SPIN` rounds of spinning, unless the environment says how
    they wait (OMP_WAIT_POLICY or GOMP_SPINCOUNT: an explicit setting is kept; the values
    this function or `no_spin` set in a parent process, still as they were, count as the
    default). Sets the process's environment, which its children inherit; a process that
    has loaded libgomp before (another library's, a parallel kernel run before reflect was
    imported) keeps what it read then."""
    global defaulted
    if os.environ.get(_MARK) is not None and os.environ[_MARK] == _held():
        defaulted = True
        return
    if "OMP_WAIT_POLICY" in os.environ or "GOMP_SPINCOUNT" in os.environ:
        return
    os.environ["OMP_WAIT_POLICY"] = "passive"
    os.environ["GOMP_SPINCOUNT"] = SPIN
    os.environ[_MARK] = _held()
    defaulted = True


def no_spin() -> None:
    """Workers sleep as soon as they are idle: for a process sharing the cores with others
    of its kind. Call before the first parallel kernel (a spawned child's initializer)."""
    os.environ["OMP_WAIT_POLICY"] = "passive"
    os.environ["GOMP_SPINCOUNT"] = "0"
    os.environ[_MARK] = _held()
