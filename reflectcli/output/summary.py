"""timings-summary.json: per-stage medians with their spread after the warm-up frames.

One file per render call of more than one render, beside the frames and their log. The first
render of a run is a warm-up (page faults, first-touch buffers, caches): it is reported apart
(`first_frame_ms`) and left out of the statistics. `warning` says when fewer than MIN_TIMED
renders follow it, or (timings_summary of one row) when the figures come from one cold frame:
a ratio of two such figures means little. A run of a single render writes no summary (its log
row is all there is)."""

from __future__ import annotations

import json

import numpy as np

from .atomic import atomic_path

WARMUP_FRAMES = 1  # renders left out of the statistics
MIN_TIMED = 3  # renders after the warm-up for a spread worth quoting


def spread_ms(seconds: list[float]) -> dict:
    """median, p25 and p75 in milliseconds (numpy's linear interpolation between the sorted
    samples: with n = 1 all three are the one sample, with n = 2 p25 and p75 lie a quarter
    of the way in from either one), and n, the samples they are of: a stage missing from
    some renders has fewer than the frame."""
    p25, median, p75 = (1e3 * float(v) for v in np.percentile(seconds, [25, 50, 75]))
    return {"median_ms": median, "p25_ms": p25, "p75_ms": p75, "n": len(seconds)}


def timings_summary(rows: list[dict], warmup: int = WARMUP_FRAMES) -> dict:
    """The summary of a run's log rows (in render order): the frame and each stage over
    the renders after `warmup` (the repeats of a frame count as renders)."""
    samples = [t for row in rows for t in row.get("repeat_seconds", [row["frame_seconds"]])]
    warm = min(warmup, len(samples) - 1)
    timed = samples[warm:]
    # each render's stages, in the same order: a still scene's repeats are timed renders
    # too (its one log row's `stages` are its first, warm-up, render's)
    renders_stages = [s for row in rows
                      for s in row.get("repeat_stages", [row.get("stages", {})])]
    stages: dict[str, list[float]] = {}
    for render in renders_stages[warm:]:
        for stage, seconds in render.items():
            stages.setdefault(stage, []).append(seconds)
    writes = [row["write_seconds"] for row in rows if "write_seconds" in row]
    warning = ""
    if warm < warmup:
        warning = (f"timings from {len(timed)} cold render(s) only: render more frames "
                   f"(>= {warmup} warm-up + {MIN_TIMED}) before comparing them")
    elif len(timed) < MIN_TIMED:
        warning = (f"only {len(timed)} render(s) after {warm} warm-up: the spread needs "
                   f">= {MIN_TIMED}")
    first = rows[0] if rows else {}
    return {
        "scene": first.get("scene"), "technique": first.get("technique"),
        "threads": first.get("threads"),
        "frames": [row["frame"] for row in rows],
        "warmup_renders": warm, "timed_renders": len(timed),
        "first_frame_ms": 1e3 * samples[0],
        "frame": spread_ms(timed),
        "stages": {stage: spread_ms(v) for stage, v in stages.items()},
        "write": spread_ms(writes) if writes else None,
        "prepare_seconds": first.get("prepare_seconds"),
        "numba_compile_seconds": first.get("numba_compile_seconds"),
        "warning": warning,
    }


def renders(rows: list[dict]) -> int:
    return sum(len(row.get("repeat_seconds", [0])) for row in rows)


def write_summary(path: str, rows: list[dict]) -> dict | None:
    """timings_summary of the rows as indented JSON, written atomically (nothing for fewer
    than two renders); the summary written."""
    if renders(rows) < 2:
        return None
    summary = timings_summary(rows)
    text = json.dumps(summary, indent=1, sort_keys=True) + "\n"
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as f:
        f.write(text)
    return summary
