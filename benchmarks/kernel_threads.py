"""Each kernel a virtual frame calls from Python, timed at 1 and 2 threads in one process:
which kernels gain from the second core and which do not.

    .venv/bin/python benchmarks/kernel_threads.py [--scene mask] [--frames 15]

Every numba dispatcher in reflect's modules is wrapped by a timer (calls from Python only;
kernels called from kernels are inside their caller's time). Frames alternate between the
thread counts in two rounds; medians of the last round per kernel, frame medians of both.
"""

from __future__ import annotations

import argparse
import collections
import statistics
import sys
import time

import numba
from numba.core.registry import CPUDispatcher
from virtual import opened


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="mask")
    ap.add_argument("--frames", type=int, default=15)
    args = ap.parse_args()
    spent: dict[str, float] = collections.defaultdict(float)

    def timed(label, kernel):
        def call(*a, **k):
            t = time.perf_counter()
            out = kernel(*a, **k)
            spent[label] += time.perf_counter() - t
            return out
        return call

    o = opened(args.scene, "virtual", [], 2)
    state = o.prepare()
    for _ in range(2):
        o.technique.forget_view(state)
        o.render_frame(0)
    for module in list(sys.modules.values()):
        name = getattr(module, "__name__", "")
        if name.startswith("reflectcli"):
            for attr, value in list(vars(module).items()):
                if isinstance(value, CPUDispatcher):
                    setattr(module, attr, timed(f"{name.rsplit('.', 1)[-1]}.{attr}", value))
    rounds: dict[int, list] = {1: [], 2: []}
    for threads in (1, 2, 1, 2):
        numba.set_num_threads(threads)
        frames, per = [], collections.defaultdict(list)
        for _ in range(args.frames):
            o.technique.forget_view(state)
            spent.clear()
            t = time.perf_counter()
            o.render_frame(0)
            frames.append(time.perf_counter() - t)
            for k, v in spent.items():
                per[k].append(v)
        rounds[threads].append((statistics.median(frames),
                                {k: statistics.median(v) for k, v in per.items()}))
    frame = {n: statistics.median(f for f, _ in rounds[n]) for n in (1, 2)}
    one, two = rounds[1][-1][1], rounds[2][-1][1]
    print(f"{args.scene}: frame {frame[1] * 1e3:.1f} ms at 1 thread, {frame[2] * 1e3:.1f} at 2 "
          f"({frame[1] / frame[2]:.2f}x); outside the kernels "
          f"{(frame[1] - sum(one.values())) * 1e3:.1f} / "
          f"{(frame[2] - sum(two.values())) * 1e3:.1f} ms")
    for k in sorted(one, key=lambda k: -one[k])[:20]:
        print(f"  {k:42s} {one[k] * 1e3:6.2f} -> {two.get(k, 0.0) * 1e3:6.2f} ms "
              f"({one[k] / max(two.get(k, 0.0), 1e-9):.2f}x)")


if __name__ == "__main__":
    main()
