"""Bench plots (matplotlib, the `plots` extra): cost against polygons, error against each
swept parameter, quality against frame time (the Pareto front) per scene, and a contact
sheet per scene (reference, image, FLIP error map).

A line joins runs that differ only in the plotted parameter: one line per scene (with its
scene overrides), technique and combination of every other override; runs of different
scenes are never joined.
"""

from __future__ import annotations

import logging
import os
import re
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..config.limits import MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE  # noqa: E402
from ..output.atomic import atomic_path  # noqa: E402
from ..output.exr import MAX_FRAME_CHANNELS, frame_problem, read_exr, size_problem  # noqa: E402
from ..output.png import linear_to_srgb  # noqa: E402
from .report import error_key, parameters_text, pareto_front, scene_groups  # noqa: E402


def _save(fig, path: str) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, bbox_inches="tight", format="png")
    plt.close(fig)


def _key_of(override: str) -> str:
    return override.split("=", 1)[0].strip()


def _short(override: str) -> str:
    return override.removeprefix("technique.")


def _lines(rows: list[dict], varying: set[str]) -> dict[tuple, list[dict]]:
    """Rows grouped so that within a group only the overrides in `varying` differ."""
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for r in rows:
        fixed = tuple(sorted(o for o in r["overrides"] if _key_of(o) not in varying))
        groups[(r["scene"], r["technique"], fixed)].append(r)
    return groups


def _label(scene: str, tech: str, fixed: tuple) -> str:
    return f"{tech} / {scene}" + (f" / {', '.join(_short(o) for o in fixed)}" if fixed else "")


def _file_part(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name)


def _number(value, digits: int) -> str:
    """A figure for a title: '-' for a missing or NaN one (not a misleading 0)."""
    if not isinstance(value, int | float) or value != value:
        return "-"
    return f"{value:.{digits}f}"


def _timed_text(rows: list[dict]) -> str:
    """How many timed renders each point's median is of, and a mark when any is warned."""
    counts = sorted({r.get("timed_frames") for r in rows if r.get("timed_frames")})
    if not counts:
        text = "the timed renders"
    else:
        span = str(counts[0]) if len(counts) == 1 else f"{counts[0]}-{counts[-1]}"
        text = f"n={span} timed renders"
    warned = sum(1 for r in rows if r.get("timing_warning"))
    return text + (f"; {warned} run(s) warned: too few renders" if warned else "")


def write_plots(out: str, rows: list[dict]) -> list[str]:
    written = []
    # frame time against polygon count: scene overrides that change the triangle count vary
    # along a line, everything else stays fixed on it
    scene_keys = {_key_of(o) for r in rows for o in r["overrides"]
                  if not _key_of(o).startswith("technique")}
    varying = {k for k in scene_keys
               if len({r["triangles"] for r in rows
                       if any(_key_of(o) == k for o in r["overrides"])}) > 1}
    if len({r["triangles"] for r in rows}) > 1 and varying:
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for (scene, tech, fixed), group in sorted(_lines(rows, varying).items()):
            pts = sorted((r["triangles"], r["frame_ms_median"]) for r in group)
            if len({p[0] for p in pts}) > 1:
                ax.plot(*zip(*pts, strict=True), marker="o", label=_label(scene, tech, fixed))
        for scene in sorted({r["scene"] for r in rows}):
            refs = sorted({(r["triangles"], r["reference_ms_median"]) for r in rows
                           if r["scene"] == scene})
            if len(refs) > 1:
                ax.plot(*zip(*refs, strict=True), marker="s", linestyle="--",
                        label=f"raytrace (ref) / {scene}")
        ax.set(xscale="log", yscale="log", xlabel="triangles",
               ylabel=f"frame time (ms, median of {_timed_text(rows)})")
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=0.3)
        written.append(os.path.join(out, "time-vs-triangles.png"))
        _save(fig, written[-1])
    # error against each swept parameter
    swept = sorted({k for r in rows for k in r["sweep"] if k.startswith("technique.")})
    for key in swept:
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for (scene, tech, fixed), group in sorted(
                _lines([r for r in rows if key in r["sweep"]], {key}).items()):
            pts = [(str(r["sweep"][key]), r["psnr_mirror"]) for r in group]
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o",
                    label=_label(scene, tech, fixed))
        ax.set(xlabel=key.removeprefix("technique."), ylabel="PSNR over mirror (dB)")
        ax.legend(fontsize=7)
        ax.grid(True, alpha=0.3)
        written.append(os.path.join(out, f"error-vs-{key.removeprefix('technique.')}.png"))
        _save(fig, written[-1])
    for scene_key, group in scene_groups(rows).items():
        written.append(os.path.join(out, "pareto-" + _file_part(
            "-".join([scene_key[0], *scene_key[1]])) + ".png"))
        _pareto_plot(group, written[-1])
    by_scene = defaultdict(list)
    for r in rows:
        by_scene[r["scene"]].append(r)
    for scene, group in by_scene.items():
        written.append(os.path.join(out, f"contact-{scene}.png"))
        _contact_sheet(group, written[-1])
    return written


def _pareto_plot(rows: list[dict], path: str) -> None:
    """Every run as a point (error against frame time), the Pareto front as a staircase."""
    column, lower = error_key(rows)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for tech in sorted({r["technique"] for r in rows}):
        pts = [(r["frame_ms_median"], r[column]) for r in rows if r["technique"] == tech]
        ax.scatter(*zip(*pts, strict=True), label=tech, zorder=3)
    front = pareto_front(rows)
    if front:
        xs = [r["frame_ms_median"] for r in front]
        ys = [r[column] for r in front]
        ax.step(xs + [max(r["frame_ms_median"] for r in rows)], ys + ys[-1:], where="post",
                color="black", linewidth=1, label="Pareto front")
        for r in front:
            ax.annotate(parameters_text(r) if r["overrides"] else r["technique"],
                        (r["frame_ms_median"], r[column]), fontsize=6,
                        xytext=(3, 3), textcoords="offset points")
    ax.set(xscale="log", xlabel=f"frame time (ms, median of {_timed_text(rows)})",
           ylabel="HDR-FLIP over mirror (lower is better)" if column == "flip_mirror"
           else "PSNR over mirror (dB)", title=f"{rows[0]['scene']}: quality at equal time")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    _save(fig, path)


def _any_frame_problem(spec) -> str | None:
    """Why a header is no frame reflect could have written (the image limits, a frame's
    channels), or None."""
    problem = size_problem(spec, MAX_IMAGE_SIDE, MAX_IMAGE_PIXELS, MAX_FRAME_CHANNELS)
    return problem or frame_problem(spec, spec.width, spec.height)


def _read_frames(r: dict, sheet: str, told: set[str]) -> tuple[dict, dict] | None:
    """A run's reference and first frame (channels), or None with a warning naming the
    first that cannot be read (each file once a sheet). Rows of an earlier bench (--resume)
    name frames that may have been damaged since, and the row's figures were measured when
    they were whole: a blank line on the sheet, not a bench that fails after its results
    are written. Headers are bounded before any pixel is read, the run's frame by its
    reference's size."""
    path = r["reference_images"][0]
    try:
        ref, _ = read_exr(path, fits=_any_frame_problem)
        height, width = ref["R"].shape  # R, G and B: _any_frame_problem
        path = r["images"][0]
        ours, _ = read_exr(path, fits=lambda spec, w=width, h=height:
                           frame_problem(spec, w, h))
    except OSError as e:
        if path not in told:
            told.add(path)
            why = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
            for prefix in (f"cannot read {path}: ", f"{path}: "):
                why = why.removeprefix(prefix)
            logging.getLogger("reflect").warning(
                "warning: %s: %s: unreadable (%s); run %s's line left blank (the bench "
                "without --resume renders it again)", os.path.basename(sheet), path, why,
                r.get("run", "?"))
        return None
    return ref, ours


def _contact_sheet(rows: list[dict], path: str) -> None:
    """One line per run: reference, the run's first frame, its LDR-FLIP error map (what a
    viewer of the two previews sees; FLIP's magma scale, 0..1); a line whose frames cannot
    be read is left blank, with a warning naming the file (_read_frames)."""
    from ..metrics import flip as flip_metric
    from ..metrics import preview

    fig, axes = plt.subplots(len(rows), 3, figsize=(9, 2.4 * len(rows)), squeeze=False)
    told: set[str] = set()
    for line, r in zip(axes, rows, strict=True):
        for ax in line:
            ax.axis("off")
        frames = _read_frames(r, path, told)
        if frames is None:
            line[1].set_title(f"run {r.get('run', '?')}: a frame unreadable (see the "
                              "warning)", fontsize=7)
            continue
        ref, ours = frames
        a = np.stack([ours[c] for c in "RGB"], axis=-1)
        b = np.stack([ref[c] for c in "RGB"], axis=-1)
        line[0].imshow(linear_to_srgb(b))
        line[1].imshow(linear_to_srgb(a))
        # the map and its mean are this frame's; the mirror figure is the run's (every
        # frame), and HDR-FLIP, as in report.md: the title says which is which
        frame = (r.get("per_frame") or [{}])[0].get("frame", "")
        if flip_metric.available():
            err = flip_metric.flip_map(preview(b), preview(a), "ldr")
            title = (f"frame {frame} LDR-FLIP {float(err.mean()):.3f} (image)\nrun "
                     f"HDR-FLIP mirror {_number(r.get('flip_mirror'), 3)}")
        else:
            err = np.abs(a - b).max(axis=-1)
            title = (f"frame {frame} |error| (no flip-evaluator)\nrun PSNR mirror "
                     f"{_number(r.get('psnr_mirror'), 1)} dB")
        im = line[2].imshow(err, cmap="magma", vmin=0, vmax=1)
        line[0].set_title(f"raytrace (reference), frame {frame}", fontsize=8)
        line[1].set_title(f"{r['technique']} {parameters_text(r)}", fontsize=7)
        line[2].set_title(title, fontsize=8)
        fig.colorbar(im, ax=line[2], fraction=0.046)
    _save(fig, path)
