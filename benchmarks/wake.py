"""How long a two-thread parallel loop takes back to back and after an idle gap, with
reflect's OpenMP settings: the guest's cost of waking its second vCPU, apart from any
renderer (the alternating Mitsuba mode and `virtual.py`'s spread both meet it).

    .venv/bin/python benchmarks/wake.py [--gap 0.3] [--tries 15]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numba
import numpy as np
from numba import njit, prange

import reflectcli  # noqa: F401  (sets how OpenMP workers wait: reflectcli/openmp.py)


@njit(parallel=True, fastmath=True, cache=True)
def _work(a, out, reps):
    for t in prange(2):
        s = 0.0
        for _ in range(reps):
            for i in range(a.shape[0]):
                s += a[i] * a[i] + 1.0
        out[t] = s


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--gap", type=float, default=0.3, help="idle seconds before each try")
    ap.add_argument("--tries", type=int, default=15)
    args = ap.parse_args()
    a, out = np.random.default_rng(0).random(4096), np.zeros(2)
    _work(a, out, 1)
    numba.set_num_threads(1)
    one = []
    for _ in range(5):
        t = time.perf_counter()
        _work(a, out, 1000)
        one.append((time.perf_counter() - t) / 2)
    numba.set_num_threads(2)
    after_gap, back_to_back = [], []
    for _ in range(args.tries):
        time.sleep(args.gap)
        t = time.perf_counter()
        _work(a, out, 1000)
        after_gap.append(time.perf_counter() - t)
        t = time.perf_counter()
        _work(a, out, 1000)
        back_to_back.append(time.perf_counter() - t)
    print(f"one thread's share at 1 thread: {statistics.median(one) * 1e3:.2f} ms "
          f"({numba.threading_layer()})")
    print(f"2 threads after a {args.gap} s gap (ms):",
          " ".join(f"{x * 1e3:.1f}" for x in after_gap))
    print("2 threads back to back (ms):     ", " ".join(f"{x * 1e3:.1f}" for x in back_to_back))


if __name__ == "__main__":
    main()
