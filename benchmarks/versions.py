"""One technique's frame in two versions of reflect, in one process: this checkout and
another commit (or folder), frames alternated round by round.

    .venv/bin/python benchmarks/versions.py --other 86ff5ca [--scene mask] \\
        [--technique virtual] [--rounds 40] [--threads 2] [--frame 0]

Why: on this machine kind a process's frame time drifts by a third over minutes (the same
code's mask frame measured 35-48 ms in one session), so two benchmark runs a few minutes
apart differ by more than a 5% change. Here both versions render in the same process, one
frame each per round (which goes first alternates), so a slow spell slows both alike; the
median of the rounds' new / old ratios is the figure to quote, with medians, p25-p75 and
minima beside it. Each frame drops the per-view caches first (`Technique.forget_view`), as
`reflect bench` does. The two versions' frames are compared channel by channel: a speed-up
meant to keep the bytes says so, or is caught.

The other version's package is copied under another name (`reflectcli_<id>`, its own
mentions of `reflectcli` renamed) into `.benchmarks/versions/`, where its compiled kernels
are kept for the next run: its first run compiles them (minutes on 2 cores). Its one-time
work (`prepare`) is done before timing.
"""

from __future__ import annotations

import argparse
import importlib
import re
import shutil
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numba
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CACHE = ROOT / ".benchmarks" / "versions"


def other_package(other: str, cache: Path = CACHE) -> str:
    """The module name of the other version's package, importable once `cache` is on
    sys.path: `other` a folder holding reflectcli/ or a git revision of this checkout."""
    folder = Path(other)
    if (folder / "reflectcli").is_dir():
        source, tag = folder / "reflectcli", "dir_" + re.sub(r"\W", "_", folder.name)
    else:
        sha = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--verify",
                              f"{other}^{{commit}}"], capture_output=True, text=True,
                             check=True).stdout.strip()
        source, tag = None, sha[:12]
    name = f"reflectcli_{tag}"
    target = cache / name
    if target.is_dir():
        return name
    cache.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=cache) as scratch:
        if source is None:  # the revision's package, from git
            archive = Path(scratch) / "src.tar"
            subprocess.run(["git", "-C", str(ROOT), "archive", "-o", str(archive), tag,
                            "reflectcli"], check=True)
            with tarfile.open(archive) as tar:
                tar.extractall(scratch, filter="data")
            source = Path(scratch) / "reflectcli"
        staged = Path(scratch) / name
        shutil.copytree(source, staged, ignore=shutil.ignore_patterns("__pycache__"))
        for path in staged.rglob("*.py"):
            text = path.read_text("utf-8")
            path.write_text(re.sub(r"\breflectcli\b", name, text), "utf-8")
        staged.rename(target)
    return name


def same_channels(a: dict, b: dict) -> bool:
    """Whether two frames' channels (api.frame_channels) are equal bit for bit."""
    return a.keys() == b.keys() and all(
        np.asarray(a[k]).dtype == np.asarray(b[k]).dtype
        and np.asarray(a[k]).tobytes() == np.asarray(b[k]).tobytes() for k in a)


def compare(other: str, scene: str, technique: str, rounds: int, threads: int,
            frame: int) -> dict:
    """{'new': seconds per round, 'old': ..., 'same': frames equal bit for bit}."""
    numba.set_num_threads(threads)
    name = other_package(other)
    sys.path.insert(0, str(CACHE))
    importlib.invalidate_caches()  # the copy may be new since the path was first looked at
    apis = {"new": importlib.import_module("reflectcli.api"),
            "old": importlib.import_module(name + ".api")}
    path = Path(scene) if scene.endswith(".toml") else ROOT / "scenes" / f"{scene}.toml"
    opened = {}
    for key, api in apis.items():
        o = api.open_scene(str(path), technique=technique, threads=threads, cache=False)
        o.prepare()
        opened[key] = o
    frames = {}
    for _ in range(2):  # warm-up rounds: compiles, caches, first-touch pages
        for key, o in opened.items():
            o.technique.forget_view(o.prepare())
            frames[key] = apis[key].frame_channels(o.render_frame(frame))
    seconds = {"new": [], "old": []}
    for r in range(rounds):
        for key in (("new", "old") if r % 2 == 0 else ("old", "new")):
            o = opened[key]
            o.technique.forget_view(o.prepare())
            t = time.perf_counter()
            done = o.render_frame(frame)
            seconds[key].append(time.perf_counter() - t)
            del done
    return {**seconds, "same": same_channels(frames["new"], frames["old"])}


def report(result: dict) -> str:
    new, old = result["new"], result["old"]
    lines = []
    for key, times in (("new", new), ("old", old)):
        q = statistics.quantiles(times, n=4)
        lines.append(f"{key}: median {statistics.median(times) * 1e3:.2f} ms (p25-p75 "
                     f"{q[0] * 1e3:.2f}-{q[2] * 1e3:.2f}), min {min(times) * 1e3:.2f} ms")
    ratios = [a / b for a, b in zip(new, old, strict=True)]
    lines.append(f"new / old: median of the rounds' ratios {statistics.median(ratios):.3f}, "
                 f"of the medians {statistics.median(new) / statistics.median(old):.3f}, "
                 f"of the minima {min(new) / min(old):.3f} ({len(ratios)} rounds)")
    lines.append("frames bit for bit: " + ("the same" if result["same"] else "DIFFERENT"))
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--other", required=True, help="a git revision, or a folder with reflectcli/")
    ap.add_argument("--scene", default="mask", help="a bundled scene's name or a .toml path")
    ap.add_argument("--technique", default="virtual")
    ap.add_argument("--rounds", type=int, default=40)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--frame", type=int, default=0)
    args = ap.parse_args()
    if args.rounds < 2:
        ap.error("--rounds: at least 2")
    print(report(compare(args.other, args.scene, args.technique, args.rounds, args.threads,
                         args.frame)))


if __name__ == "__main__":
    main()
