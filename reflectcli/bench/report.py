"""Bench outputs: results.csv, report.md and plots, each written atomically."""

from __future__ import annotations

import csv
import io
import json
import math

from ..output.atomic import atomic_path

_METRIC_COLUMNS = [f"{m}_{scope}" for scope in ("mirror", "image") for m in (
    "psnr", "rmse", "max_error", "frac_off", "relmse", "p50", "p95", "p99", "flip", "flip_ldr",
    "ssim", "temporal")]
CSV_COLUMNS = [
    "run", "scene", "technique", "sweep", *_METRIC_COLUMNS,
    "hole_fraction", "unreached_fraction", "frame_ms_median", "frame_ms_p25", "frame_ms_p75",
    "timing_warning", "reference_ms_median", "reference_timing_warning", "capture_ms_per_frame",
    "prepare_seconds", "first_frame_ms", "numba_compile_seconds",
    "triangles", "frames", "repeats", "warmup_renders", "timed_frames", "threads", "cpu",
    "parameters", "overrides", "scene_file",
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


def parameters_text(row: dict) -> str:
    """Every override of the run, `set` and sweep alike (technique. prefix dropped)."""
    return ", ".join(o.removeprefix("technique.") for o in row["overrides"]) or "defaults"


def _finite(value) -> bool:
    return isinstance(value, int | float) and math.isfinite(value)


def error_key(rows: list[dict]) -> tuple[str, bool]:
    """(column, lower is better) ranking quality: FLIP over the mirror if measured, else
    PSNR over the mirror."""
    if any(_finite(r.get("flip_mirror")) for r in rows):
        return "flip_mirror", True
    return "psnr_mirror", False


def pareto_front(rows: list[dict]) -> list[dict]:
    """The runs no other run beats on both frame time and quality, fastest first: for a
    time budget, the best quality any run reaches within it is on this front."""
    key, lower = error_key(rows)
    scored = [r for r in rows if _finite(r.get(key)) or r.get(key) == math.inf]
    scored.sort(key=lambda r: (r["frame_ms_median"], r[key] if lower else -r[key]))
    front, best = [], None
    for r in scored:
        if best is None or (r[key] < best if lower else r[key] > best):
            front.append(r)
            best = r[key]
    return front


def scene_groups(rows: list[dict]) -> dict[tuple, list[dict]]:
    """Rows by scene and scene overrides (a different scene content is a different scene)."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault(_scene_key(r), []).append(r)
    return groups


def scene_label(key: tuple) -> str:
    return key[0] + (f" ({', '.join(key[1])})" if key[1] else "")


def _frames_of(row: dict) -> tuple | None:
    """The frames a row was scored and timed on (None: not recorded)."""
    return tuple(f.get("frame") for f in row.get("per_frame", [])) or None


def _same_frames(a: dict, b: dict) -> bool:
    fa, fb = _frames_of(a), _frames_of(b)
    return fa is None or fb is None or fa == fb


def rerender_for(row: dict, rows: list[dict]) -> tuple[float, bool] | None:
    """The `x rerender` ratio's other side: (frame ms, marked) of the rerender run timed on
    the same scene, scene overrides and frames as `row`; of several (a rerender sweep), the
    one at rerender's defaults; None when there is none or no way to choose. Marked when
    that run is warned or was timed at another thread count or on another CPU."""
    if row["technique"] == "rerender":
        same = [row]
    else:
        same = [r for r in rows if r["technique"] == "rerender"
                and _scene_key(r) == _scene_key(row) and _same_frames(r, row)]
        if len(same) > 1:
            same = [r for r in same if not any(o.startswith("technique")
                                               for o in r["overrides"])]
    if len(same) != 1:
        return None
    (rr,) = same
    marked = bool(rr.get("timing_warning")) or any(
        rr.get(key) != row.get(key) for key in ("threads", "cpu"))
    return rr["frame_ms_median"], marked


def machines_text(rows: list[dict]) -> str:
    """Every CPU and thread count the rows were timed on (resumed rows may differ)."""
    seen: dict[tuple, int] = {}
    for r in rows:
        key = (r["cpu"], r["threads"])
        seen[key] = seen.get(key, 0) + 1
    parts = [f"{cpu}, {threads} threads" + (f" ({n} of {len(rows)} runs)" if len(seen) > 1
                                            else "")
             for (cpu, threads), n in seen.items()]
    return "; ".join(parts)


BUSY_EXTRA = 1.0  # runnable threads beyond the cores, on average, that make a machine busy


def busy_rows(rows: list[dict]) -> list[dict]:
    """The rows timed while the machine's 1-minute load average (the bench's own threads
    included) exceeded its cores by more than BUSY_EXTRA: at least one thread waiting for a
    core all along, on average."""
    return [r for r in rows
            if r.get("cores") and max((v for v in r.get("load_1min") or [] if v is not None),
                                      default=0.0) > r["cores"] + BUSY_EXTRA]


def load_text(rows: list[dict]) -> list[str]:
    """The machine's 1-minute load average around the runs, and a warning when it exceeded
    the cores: frame times (and their ratios) then include waiting for the cores."""
    loads = [v for r in rows for v in r.get("load_1min") or [] if v is not None]
    if not loads:
        return []
    cores = max((r.get("cores") or 0) for r in rows)
    text = f"Load average (1 min) around the runs: {min(loads):.1f}-{max(loads):.1f}"
    text += f" on {cores} cores." if cores else "."
    busy = busy_rows(rows)
    if busy:
        text += (f" **{len(busy)} of {len(rows)} runs were timed on a busy machine (load "
                 f"above the cores + {BUSY_EXTRA:g}, this bench's threads included): their "
                 "frame times include waiting for the cores, and "
                 "ratios between runs timed at different loads are not figures to quote.**")
    return [text, ""]


def report_markdown(name: str, rows: list[dict], total: int | None = None) -> str:
    lines = [f"# Bench `{name}`", "",
             "Against the ray tracer: PSNR (dB, peak 1; inf = identical), HDR-FLIP of the linear "
             "images (0 = identical, 1 = most different), SSIM of the sRGB-encoded images "
             "(1 = identical), relative MSE, p99 of the per-pixel error and the temporal error "
             "(RMSE of the frame-to-frame change against the reference's; '-' for one frame), "
             "over mirror pixels and over the whole image, averaged over frames. Frame time is "
             "the median (p25-p75) of the n timed renders after the warm-up ones (every "
             "frame's renders together; percentiles by linear interpolation between the "
             "sorted renders, numpy's default: with n = 1 the three are one render, with "
             "n = 2 p25 and p75 lie a quarter of the way in from either render, so a spread "
             "of fewer than 3 renders is not a spread); one-time work "
             "(prepare: map capture, decomposition, ...) is its own column and never in frame "
             "time; 'first' is the first render (warm-up: first-frame caches, JIT). Ratios are "
             "ratios of the two runs' median frame times on the same scene, scene overrides "
             "and frames ('x rerender': the rerender run at its defaults when there are "
             "several; '-' when there is none); a ratio marked * has a side timed on "
             "too few renders or with no warm-up (its frame time says which), or its sides "
             "were timed at different thread counts or on different CPUs: it is not a "
             "figure to quote. 'holes': of the mirror pixels whose "
             "reflected ray meets geometry in the reference, those the technique left empty; "
             "'unreached': every mirror pixel it did not reach, background reflections "
             "included.", ""]
    if total is not None and len(rows) < total:
        lines += [f"**Incomplete: {len(rows)} of {total} runs finished** (the bench was "
                  "interrupted or a run failed; `--resume` continues). Ratios and rankings "
                  "cover the finished runs only.", ""]
    if rows:
        first = rows[0]
        lines += [f"Machine: {machines_text(rows)}; versions: "
                  + ", ".join(f"{k} {v}" for k, v in sorted(first["versions"].items())), ""]
        lines += load_text(rows)
    for scene in sorted({r["scene"] for r in rows}):
        lines += [f"## {scene}", "",
                  "| technique | parameters | PSNR mirror | FLIP mirror | SSIM mirror "
                  "| relMSE mirror | p99 mirror | temporal mirror | PSNR image | FLIP image "
                  "| holes | unreached | frame ms median (p25-p75, n) | one-time s | first ms "
                  "| x rerender | x raytrace | triangles |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in (r for r in rows if r["scene"] == scene):
            rr, rr_warned = rerender_for(r, rows) or (None, False)
            timing = (f"{_fmt(r['frame_ms_median'])} ({_fmt(r['frame_ms_p25'])}-"
                      f"{_fmt(r['frame_ms_p75'])}, n={r.get('timed_frames', '?')})")
            if r.get("timing_warning"):
                timing += f" **warning: {r['timing_warning']}**"
            # a ratio is only as sound as its worse side: marked when either side is warned
            mark = "*" if r.get("timing_warning") else ""
            x_rerender = (_fmt(r["frame_ms_median"] / rr, 2)
                          + (mark or ("*" if rr_warned else ""))
                          if rr else "-")
            x_raytrace = (_fmt(r["frame_ms_median"] / r["reference_ms_median"], 2)
                          + (mark or ("*" if r.get("reference_timing_warning") else "")))
            lines.append(
                f"| {r['technique']} | {parameters_text(r)} | {_fmt(r['psnr_mirror'])} | "
                f"{_fmt(r.get('flip_mirror'), 3)} | {_fmt(r.get('ssim_mirror'), 3)} | "
                f"{_fmt(r.get('relmse_mirror'), 3)} | {_fmt(r.get('p99_mirror'), 3)} | "
                f"{_fmt(r.get('temporal_mirror'), 3)} | {_fmt(r['psnr_image'])} | "
                f"{_fmt(r.get('flip_image'), 3)} | {_fmt(100 * r['hole_fraction'], 2)}% | "
                f"{_fmt(100 * r.get('unreached_fraction', 0.0), 2)}% | "
                f"{timing} | {_fmt(r.get('prepare_seconds'), 2)} | "
                f"{_fmt(r.get('first_frame_ms'))} | "
                f"{x_rerender} | {x_raytrace} | "
                f"{r['triangles']} |")
        lines.append("")
        for key, group in scene_groups([r for r in rows if r["scene"] == scene]).items():
            column, lower = error_key(group)
            label = "FLIP mirror" if column == "flip_mirror" else "PSNR mirror"
            lines += [f"### Quality at equal time budget: {scene_label(key)}", "",
                      f"The Pareto front of {label} against frame time: with a budget of a "
                      "row's frame time, its run is the best any run here reaches; runs "
                      "not listed are beaten on both.", "",
                      f"| budget ms | technique | parameters | {label} | PSNR mirror |",
                      "|---|---|---|---|---|"]
            for r in pareto_front(group):
                lines.append(f"| {_fmt(r['frame_ms_median'])} | **{r['technique']}** | "
                             f"{parameters_text(r)} | {_fmt(r[column], 3)} | "
                             f"{_fmt(r['psnr_mirror'])} |")
            lines.append("")
    return "\n".join(lines) + "\n"
