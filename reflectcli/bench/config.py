"""Bench matrices: which scenes, techniques and parameter sweeps to run, and how.

Every size has a limit: the number of runs is counted from the list lengths before a single
job is made (each job opens its scene to be checked, so a huge matrix would take minutes to
refuse), and warm-up, repeats and worker processes are bounded.
"""

from __future__ import annotations

import datetime
import itertools
import json
import math
import os
from typing import Any

from pydantic import Field, field_validator

from ..config.base import Strict
from ..config.names import NAME_PATTERN
from ..errors import Problem

MAX_RUNS = 2000  # jobs in one bench file (validate opens each one's scene: ~10 ms a job)
MAX_WARMUP = 100  # leading renders left out of a run's timings
MAX_REPEATS = 100  # renders of each frame
MAX_WORKERS = 64  # local worker processes (`bench --workers`)


class RunGroup(Strict):
    """One block of the matrix: every scene x technique x combination of the sweep values."""

    scenes: list[str] = Field(min_length=1, description="scene files (relative to this file)")
    techniques: list[str] = Field(min_length=1)
    set: list[str] = Field(default_factory=list, description="KEY=VALUE overrides for all")
    sweep: dict[str, list[Any]] = Field(default_factory=dict, description="KEY = [values]")
    frames: str | None = Field(default=None, description="this block's frames (N or A:B); "
                               "default: the bench's")


class BenchSection(Strict):
    name: str = Field(pattern=NAME_PATTERN)

    @field_validator("name")
    @classmethod
    def _a_folder_name(cls, name: str) -> str:
        """The default output folder is out/bench/<name>: '..' would put the bench's files in
        out/ itself (as scene.name, '.' and '..' are no names)."""
        if name in (".", ".."):
            raise ValueError("must name a folder ('.' and '..' are not names)")
        return name
    frames: str = Field(default="0:3", description="frames of each run: N or A:B")
    warmup: int = Field(default=1, ge=0, le=MAX_WARMUP,
                        description="leading renders left out of timings")
    repeats: int = Field(default=1, ge=1, le=MAX_REPEATS, description="renders of each frame "
                         "(a one-frame scene needs warmup + 3 for an honest median)")
    threshold: float = Field(default=0.1, gt=0, allow_inf_nan=False,
                             description="error counted as 'off'")
    reference_depth: int = Field(default=1, ge=0, description="raytrace max_depth")
    out: str | None = Field(default=None, min_length=1, description="relative to this file; "
                            "default: out/bench/<name> in the working directory")
    plots: bool = True


class BenchConfig(Strict):
    bench: BenchSection
    runs: list[RunGroup] = Field(min_length=1)


def group_runs(group: RunGroup) -> int:
    """Jobs a group expands to (an empty sweep list counted as absent: it is refused)."""
    return (len(group.scenes) * len(group.techniques)
            * math.prod(len(v) for v in group.sweep.values() if v))


def run_count(cfg: BenchConfig) -> int:
    return sum(group_runs(g) for g in cfg.runs)


def matrix_problems(cfg: BenchConfig, display: str) -> list[Problem]:
    """Empty sweep lists (each would silently drop its group) and a matrix past MAX_RUNS,
    found from the list lengths alone."""
    problems = [Problem(display, f"runs.{i}.sweep.{key}",
                        "empty list (give at least one value, or leave the key out)")
                for i, group in enumerate(cfg.runs)
                for key, values in group.sweep.items() if not values]
    total = run_count(cfg)
    if total > MAX_RUNS:
        sizes = [group_runs(g) for g in cfg.runs]
        big = max(range(len(sizes)), key=sizes.__getitem__)
        problems.append(Problem(display, "runs", f"{total:,} runs (scenes x techniques x sweep "
                                f"values; runs.{big} alone has {sizes[big]:,}); a bench file "
                                f"may have at most {MAX_RUNS:,}"))
    return problems


def expand(cfg: BenchConfig, source: str) -> list[dict]:
    """The matrix as a list of jobs: {scene (path), technique, overrides, sweep (dict)}.
    Sweep keys with no values are left out (matrix_problems reports them), so that the
    rest of the matrix is still checked."""
    here = os.path.dirname(os.path.abspath(source))
    jobs = []
    for index, group in enumerate(cfg.runs):
        keys = [k for k, v in group.sweep.items() if v]
        for scene in group.scenes:
            path = os.path.normpath(os.path.join(here, scene))
            for technique in group.techniques:
                for values in itertools.product(*(group.sweep[k] for k in keys)):
                    sweep = dict(zip(keys, values, strict=True))
                    overrides = list(group.set) + [f"{k}={_toml(v)}" for k, v in sweep.items()]
                    # the bench file's field each override comes from, for its problems
                    fields = ([(o.split("=", 1)[0].strip(), f"runs.{index}.set")
                               for o in group.set]
                              + [(k, f"runs.{index}.sweep.{k}") for k in sweep])
                    jobs.append({"scene": path, "technique": technique,
                                 "overrides": overrides, "sweep": sweep,
                                 "override_fields": fields,
                                 "techniques_field": f"runs.{index}.techniques",
                                 "frames": group.frames or cfg.bench.frames,
                                 "frames_field": (f"runs.{index}.frames" if group.frames
                                                  else "bench.frames")})
    return jobs


def _toml(value: Any) -> str:
    """A sweep value written back as the TOML a `--set` parses into the same value: strings
    escaped (JSON's escapes are TOML's), arrays and tables inline, dates as ISO text (Python's
    repr wrote a table as `{'frames': 2}`, refused as "must be a table", and a backslash in a
    string unescaped)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(str(k), ensure_ascii=False)} = {_toml(v)}"
                               for k, v in value.items()) + "}"
    if isinstance(value, (datetime.date, datetime.time)):
        return value.isoformat()
    return repr(value)  # int, float (nan and inf are TOML words too)
