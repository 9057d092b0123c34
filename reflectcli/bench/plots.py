"""Bench plots (matplotlib, the `plots` extra): cost against polygons, error against each
swept parameter, and a contact sheet per scene (reference, image, error heat map)."""

from __future__ import annotations

import os
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..output.atomic import atomic_path  # noqa: E402
from ..output.exr import read_exr  # noqa: E402
from ..output.png import linear_to_srgb  # noqa: E402


def _save(fig, path: str) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, bbox_inches="tight", format="png")
    plt.close(fig)


def write_plots(out: str, rows: list[dict]) -> list[str]:
    written = []
    by_scene = defaultdict(list)
    for r in rows:
        by_scene[r["scene"]].append(r)
    # frame time against polygon count, per technique
    if len({r["triangles"] for r in rows}) > 1:
        fig, ax = plt.subplots(figsize=(6, 4))
        for tech in sorted({r["technique"] for r in rows}):
            pts = sorted((r["triangles"], r["frame_ms_median"]) for r in rows
                         if r["technique"] == tech)
            ax.plot(*zip(*pts, strict=True), marker="o", label=tech)
        refs = sorted({(r["triangles"], r["reference_ms_median"]) for r in rows})
        ax.plot(*zip(*refs, strict=True), marker="s", linestyle="--", label="raytrace (ref)")
        ax.set(xscale="log", yscale="log", xlabel="triangles", ylabel="frame time (ms)")
        ax.legend()
        ax.grid(True, which="both", alpha=0.3)
        written.append(os.path.join(out, "time-vs-triangles.png"))
        _save(fig, written[-1])
    # error against each swept parameter
    swept = sorted({k for r in rows for k in r["sweep"] if k.startswith("technique.")})
    for key in swept:
        fig, ax = plt.subplots(figsize=(6, 4))
        for (scene, tech), group in _groups(rows, key).items():
            pts = [(str(r["sweep"][key]), r["psnr_mirror"]) for r in group]
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o",
                    label=f"{tech} / {scene}")
        ax.set(xlabel=key.removeprefix("technique."), ylabel="PSNR over mirror (dB)")
        ax.legend(fontsize=7)
        ax.grid(True, alpha=0.3)
        written.append(os.path.join(out, f"error-vs-{key.removeprefix('technique.')}.png"))
        _save(fig, written[-1])
    for scene, group in by_scene.items():
        written.append(os.path.join(out, f"contact-{scene}.png"))
        _contact_sheet(group, written[-1])
    return written


def _groups(rows, key):
    groups = defaultdict(list)
    for r in rows:
        if key in r["sweep"]:
            groups[(r["scene"], r["technique"])].append(r)
    return groups


def _contact_sheet(rows: list[dict], path: str) -> None:
    """One line per run: reference, the run's first frame, |error| (max over channels)."""
    fig, axes = plt.subplots(len(rows), 3, figsize=(9, 2.4 * len(rows)), squeeze=False)
    for line, r in zip(axes, rows, strict=True):
        ours, _ = read_exr(r["images"][0])
        ref, _ = read_exr(r["reference_images"][0])
        a = np.stack([ours[c] for c in "RGB"], axis=-1)
        b = np.stack([ref[c] for c in "RGB"], axis=-1)
        err = np.abs(a - b).max(axis=-1)
        line[0].imshow(linear_to_srgb(b))
        line[1].imshow(linear_to_srgb(a))
        im = line[2].imshow(err, cmap="inferno", vmin=0, vmax=1)
        sweep = ", ".join(f"{k.split('.')[-1]}={v}" for k, v in r["sweep"].items())
        line[0].set_title("raytrace (reference)", fontsize=8)
        line[1].set_title(f"{r['technique']} {sweep}", fontsize=8)
        line[2].set_title(f"|error|, PSNR mirror {r['psnr_mirror']:.1f} dB", fontsize=8)
        for ax in line:
            ax.axis("off")
        fig.colorbar(im, ax=line[2], fraction=0.046)
    _save(fig, path)
