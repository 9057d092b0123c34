"""`make fuzz`: many mutated bundled scenes through validate and render (reflectcli/fuzz.py).

Each config runs in a worker process with a time limit (CPU seconds of the worker, or ten
times that of wall time), so a hang is caught and counted (the worker is killed and
replaced). Prints the figure: configs, tracebacks, hangs, validate/render disagreements,
other failures; writes every failure with its seed to --report.

    .venv/bin/python scripts/fuzz.py --count 10000 --timeout 60 --report out/fuzz.jsonl
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import sys
import tempfile
import time


def worker(conn, folder: str) -> None:
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    import logging

    logging.getLogger("reflect").setLevel(logging.CRITICAL)
    from reflectcli.fuzz import base_scenes, check, one_case

    bases = base_scenes()
    while True:
        seed = conn.recv()
        if seed is None:
            return
        name, text = one_case(seed, bases)
        path = os.path.join(folder, f"fuzz-{seed}.toml")
        with open(path, "w") as f:
            f.write(text)
        result = check(path, os.path.join(folder, "out"), os.path.join(folder, "cache"))
        os.unlink(path)
        result.update(seed=seed, scene=name)
        conn.send(result)


def _cpu_seconds(pid: int) -> float:
    """CPU time (user + system, all threads) of a process so far; 0 if unknown."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return 0.0


def _answered(conn, pid: int, limit: float) -> bool:
    """Wait for the worker's answer. A hang is `limit` seconds of the worker's CPU time (on
    a shared, loaded machine wall time says little), or ten times `limit` of wall time."""
    start_cpu, start = _cpu_seconds(pid), time.time()
    while not conn.poll(1.0):
        if (_cpu_seconds(pid) - start_cpu > limit or time.time() - start > 10 * limit):
            return False
    return True


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--count", type=int, default=10000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--report", default="out/fuzz.jsonl")
    args = ap.parse_args()
    os.makedirs(os.path.dirname(os.path.abspath(args.report)), exist_ok=True)
    ctx = mp.get_context("spawn")
    folder = tempfile.mkdtemp(prefix="reflect-fuzz-")
    counts = {"configs": 0, "traceback": 0, "hang": 0, "disagree": 0, "message": 0,
              "wrote": 0, "validate_ok": 0, "render_ok": 0}
    proc = conn = None
    start = time.time()
    with open(args.report, "w") as report:
        for seed in range(args.seed, args.seed + args.count):
            if proc is None:
                conn, child = ctx.Pipe()
                proc = ctx.Process(target=worker, args=(child, folder), daemon=True)
                proc.start()
                first = True
            conn.send(seed)
            # the first config of a worker also loads numba's kernels: allow for it
            if _answered(conn, proc.pid, args.timeout + (120 if first else 0)):
                try:
                    result = conn.recv()
                except EOFError:  # the worker died (a crash in native code)
                    result = {"seed": seed, "failure": "traceback", "detail": "worker died"}
                    proc = None
            else:
                proc.kill()
                proc.join()
                proc = None
                result = {"seed": seed, "failure": "hang", "detail": f"> {args.timeout} s"}
            first = False
            if proc is not None and not proc.is_alive():
                proc = None
            counts["configs"] += 1
            counts["validate_ok"] += result.get("validate") == "ok"
            counts["render_ok"] += result.get("render") == "ok"
            if result["failure"]:
                counts[result["failure"]] += 1
                report.write(json.dumps(result) + "\n")
                report.flush()
            if counts["configs"] % 100 == 0:
                print(json.dumps({**counts, "seconds": round(time.time() - start)}),
                      flush=True)
    if proc is not None:
        conn.send(None)
        proc.join(10)
    print(json.dumps({**counts, "seconds": round(time.time() - start)}))
    bad = sum(counts[k] for k in ("traceback", "hang", "disagree", "message", "wrote"))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
