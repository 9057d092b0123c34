"""Bench outputs: results.csv, report.md and plots, each written atomically."""

from __future__ import annotations

import csv
import io
import json
import math
import os

from ..output.atomic import atomic_path

CSV_COLUMNS = [
    "run", "scene", "technique", "sweep", "psnr_mirror", "rmse_mirror", "max_error_mirror",
    "frac_off_mirror", "psnr_image", "rmse_image", "max_error_image", "frac_off_image",
    "hole_fraction", "frame_ms_median", "frame_ms_p25", "frame_ms_p75", "reference_ms_median",
    "capture_ms_per_frame",
    "precompute_seconds", "numba_compile_seconds", "triangles", "frames", "timed_frames",
    "threads", "cpu", "parameters", "overrides", "scene_file",
]


def _cell(value) -> str:
    if isinstance(value, dict | list):
        return json.dumps(value, sort_keys=True)
    if isinstance(value, float):
        return repr(value)
    return str(value)


def write_text(path: str, text: str) -> None:
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as f:
        f.write(text)


def write_csv(path: str, rows: list[dict]) -> None:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for row in rows:
        writer.writerow([_cell(row.get(c, "")) for c in CSV_COLUMNS])
    write_text(path, buf.getvalue())


def _fmt(value, digits=1) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    if isinstance(value, float) and math.isinf(value):
        return "inf"
    return f"{value:.{digits}f}"


def _scene_key(row: dict) -> tuple:
    """Runs of a scene comparable for time ratios: same scene overrides."""
    scene_part = sorted(o for o in row["overrides"] if not o.startswith("technique"))
    return (row["scene"], tuple(scene_part))


def report_markdown(name: str, rows: list[dict]) -> str:
    lines = [f"# Bench `{name}`", "",
             "PSNR over mirror pixels and over the whole image against the ray tracer "
             "(dB; inf = identical); frame time is the median after the warm-up frames; "
             "ratios are frame-time ratios measured in this run.", ""]
    rerender = {_scene_key(r): r["frame_ms_median"] for r in rows if r["technique"] == "rerender"}
    if rows:
        first = rows[0]
        lines += [f"Machine: {first['cpu']}, {first['threads']} threads; versions: "
                  + ", ".join(f"{k} {v}" for k, v in sorted(first["versions"].items())), ""]
    for scene in sorted({r["scene"] for r in rows}):
        lines += [f"## {scene}", "",
                  "| technique | parameters | PSNR mirror | PSNR image | holes | frame ms "
                  "| x rerender | x raytrace | triangles |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for r in (r for r in rows if r["scene"] == scene):
            sweep = ", ".join(f"{k.removeprefix('technique.')}={v}" for k, v in r["sweep"].items())
            rr = rerender.get(_scene_key(r))
            lines.append(
                f"| {r['technique']} | {sweep or '-'} | {_fmt(r['psnr_mirror'])} | "
                f"{_fmt(r['psnr_image'])} | {_fmt(100 * r['hole_fraction'], 2)}% | "
                f"{_fmt(r['frame_ms_median'])} | "
                f"{_fmt(r['frame_ms_median'] / rr, 2) if rr else '-'} | "
                f"{_fmt(r['frame_ms_median'] / r['reference_ms_median'], 2)} | "
                f"{r['triangles']} |")
        lines.append("")
    return "\n".join(lines) + "\n"


def write_outputs(plan, rows: list[dict]) -> None:
    out = plan.out
    write_csv(os.path.join(out, "results.csv"), rows)
    write_text(os.path.join(out, "report.md"), report_markdown(plan.config.bench.name, rows))
    if plan.config.bench.plots:
        try:
            from .plots import write_plots
        except ImportError:
            return  # matplotlib is an optional extra
        write_plots(out, rows)
