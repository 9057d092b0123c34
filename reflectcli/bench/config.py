"""Bench matrices: which scenes, techniques and parameter sweeps to run, and how."""

from __future__ import annotations

import itertools
import os
from typing import Any

from pydantic import Field

from ..config.base import Strict


class RunGroup(Strict):
    """One block of the matrix: every scene x technique x combination of the sweep values."""

    scenes: list[str] = Field(min_length=1, description="scene files (relative to this file)")
    techniques: list[str] = Field(min_length=1)
    set: list[str] = Field(default_factory=list, description="KEY=VALUE overrides for all")
    sweep: dict[str, list[Any]] = Field(default_factory=dict, description="KEY = [values]")
    frames: str | None = Field(default=None, description="this block's frames (N or A:B); "
                               "default: the bench's")


class BenchSection(Strict):
    name: str = Field(pattern=r"^[A-Za-z0-9._-]+$")
    frames: str = Field(default="0:3", description="frames of each run: N or A:B")
    warmup: int = Field(default=1, ge=0, description="leading renders left out of timings")
    repeats: int = Field(default=1, ge=1, le=100, description="renders of each frame (a "
                         "one-frame scene needs warmup + 3 for an honest median)")
    threshold: float = Field(default=0.1, gt=0, description="error counted as 'off'")
    reference_depth: int = Field(default=1, ge=0, description="raytrace max_depth")
    out: str | None = Field(default=None, description="relative to this file; default: "
                            "out/bench/<name> in the working directory")
    plots: bool = True


class BenchConfig(Strict):
    bench: BenchSection
    runs: list[RunGroup] = Field(min_length=1)


def expand(cfg: BenchConfig, source: str) -> list[dict]:
    """The matrix as a list of jobs: {scene (path), technique, overrides, sweep (dict)}."""
    here = os.path.dirname(os.path.abspath(source))
    jobs = []
    for group in cfg.runs:
        keys = list(group.sweep)
        for scene in group.scenes:
            path = os.path.normpath(os.path.join(here, scene))
            for technique in group.techniques:
                for values in itertools.product(*(group.sweep[k] for k in keys)):
                    sweep = dict(zip(keys, values, strict=True))
                    overrides = list(group.set) + [f"{k}={_toml(v)}" for k, v in sweep.items()]
                    jobs.append({"scene": path, "technique": technique,
                                 "overrides": overrides, "sweep": sweep,
                                 "frames": group.frames or cfg.bench.frames})
    return jobs


def _toml(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace('"', '\\"') + '"'
    return repr(value)
