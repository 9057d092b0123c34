"""Environment variables that reflect's libraries read when they load, checked before any
command runs: a value numba or libgomp cannot use was a traceback at the first kernel
(`NUMBA_NUM_THREADS=0`, `NUMBA_THREADING_LAYER=bogus`, `tbb` without Intel TBB installed)
or a warning quoting one, after which the value was ignored (`NUMBA_NUM_THREADS=abc`;
`OMP_WAIT_POLICY=bogus`: libgomp's own line). Each is one line naming the variable."""

from __future__ import annotations

import importlib
import os
import re
from collections.abc import Mapping

from .errors import Problem

MAX_THREADS = 1024  # NUMBA_NUM_THREADS: worker threads numba starts for every parallel kernel
THREADING_LAYERS = ("default", "safe", "forksafe", "threadsafe", "omp", "tbb", "workqueue")
NEEDS_TBB = ("tbb", "safe")  # numba's layers that exist only with Intel TBB installed
WAIT_POLICIES = ("active", "passive")  # OMP_WAIT_POLICY, any case (libgomp)


def _tbb_loads() -> bool:
    """Whether numba's TBB layer can load (its extension needs libtbb)."""
    try:
        importlib.import_module("numba.np.ufunc.tbbpool")
    except (ImportError, OSError):
        return False
    return True


def environment_problems(env: Mapping[str, str] | None = None) -> list[Problem]:
    """One Problem per variable whose value the libraries cannot use."""
    env = os.environ if env is None else env
    problems = []

    def add(name: str, message: str) -> None:
        problems.append(Problem("environment", name, f"{message} (is '{env[name]}')"))

    threads = env.get("NUMBA_NUM_THREADS")
    if threads is not None and not (re.fullmatch(r"[0-9]{1,9}", threads)
                                    and 1 <= int(threads) <= MAX_THREADS):
        add("NUMBA_NUM_THREADS", f"must be a whole number 1..{MAX_THREADS}")
    layer = env.get("NUMBA_THREADING_LAYER")
    if layer is not None:
        if layer not in THREADING_LAYERS:
            add("NUMBA_THREADING_LAYER", f"must be one of {', '.join(THREADING_LAYERS)}")
        elif layer in NEEDS_TBB and not _tbb_loads():
            add("NUMBA_THREADING_LAYER", "needs Intel TBB, which is not installed "
                                         "(pip install tbb, or leave the variable out)")
    policy = env.get("OMP_WAIT_POLICY")
    if policy is not None and policy.strip().lower() not in WAIT_POLICIES:
        add("OMP_WAIT_POLICY", f"must be {' or '.join(WAIT_POLICIES)}")
    return problems
