"""ssr and ppr at 640x480: ms per frame (primary pass apart), cells per ray, hiz rays per
second, and against the ground truth: PSNR over hit pixels vs rerender and the hit mask's
precision and recall vs where the ray tracer's reflected ray lands on a surface the frame
shows (medians of repeated frame-0 renders after a warm-up, 2 threads).

    .venv/bin/python benchmarks/screenspace.py [--repeats 5] [--scenes teapot-box ...]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from reflectcli import api
from reflectcli.raster.primary import render_primary
from reflectcli.screenspace.rays import mirror_rays

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from naive_screenspace import truth_hits  # noqa: E402

VARIANTS = [
    ("raster", "raster", []),
    ("rerender", "rerender", ["technique.max_depth=1"]),
    ("ssr linear", "ssr", ['technique.march="linear"']),
    ("ssr dda", "ssr", ['technique.march="dda"']),
    ("ssr hiz", "ssr", ['technique.march="hiz"']),
    ("ppr", "ppr", []),
]
PRIMARY = ("rasterize", "shade")


def run(path, technique, overrides, repeats):
    opened = api.open_scene(path, overrides=overrides, technique=technique, threads=2,
                            cache=False)
    built = opened.scene
    tech = opened.technique
    state = tech.prepare(built)
    cam = opened.camera(0)
    tech.render(state, 0, cam)
    rows = []
    for _ in range(repeats):
        t = time.perf_counter()
        f = tech.render(state, 0, cam)
        rows.append((time.perf_counter() - t, f))
    return rows, built, cam


def psnr(a, b):
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(1 / mse)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--scenes", nargs="+",
                    default=["teapot-box", "teapot-floor", "ssr-shapes", "grazing-floor"])
    args = ap.parse_args()
    size = ["camera.width=640", "camera.height=480"]
    print("| scene | technique | ms/frame | primary ms | reflection ms | cells/ray | "
          "PSNR hits (pixel / surface) | precision | recall |")
    print("|---|---|---|---|---|---|---|---|---|")
    for scene in args.scenes:
        path = str(ROOT / "scenes" / f"{scene}.toml")
        ref = None
        visible = None
        for label, technique, extra in VARIANTS:
            rows, built, cam = run(path, technique, size + extra, args.repeats)
            total = statistics.median(r[0] for r in rows) * 1e3
            prim = statistics.median(sum(r[1].timings.get(k, 0.0) for k in PRIMARY)
                                     for r in rows) * 1e3
            f = rows[-1][1]
            if technique == "rerender":
                ref = f
                primary = render_primary(built, 0, cam)
                rays, valid = mirror_rays(primary.buffers, primary.frame.surface,
                                          built.n_objects, primary.triangles, built.mirrors,
                                          cam, cam.far)
                visible, _ = truth_hits(rays, valid, built.geometry(0), primary.frame.depth,
                                        primary.frame.surface, cam)
            cells = f.stats.get("cells_per_ray")
            hit_key = f"{technique}_hit"
            cols = ["", "", ""]
            if hit_key in f.extra and ref is not None:
                hit = f.extra[hit_key] > 0
                # each resolve asked for by name: the row's own frame is the default's
                pix, surf = (run(path, technique, size + extra + [f'technique.resolve="{r}"'],
                                 1)[0][0][1] for r in ("pixel", "surface"))
                tp = float((hit & visible).sum())
                cols = [f"{psnr(ref.rgb[hit], pix.rgb[hit]):.1f} / "
                        f"{psnr(ref.rgb[hit], surf.rgb[hit]):.1f}",
                        f"{tp / max(hit.sum(), 1):.4f}", f"{tp / max(visible.sum(), 1):.4f}"]
            extra_ms = total - prim
            cell = "" if cells is None else f"{cells:.1f}"
            if label == "ssr hiz" and f.timings.get("march"):
                cell += f" ({f.stats['ssr_rays'] / f.timings['march'] / 1e6:.1f} M rays/s)"
            print(f"| {scene} | {label} | {total:.1f} | {prim:.1f} | {extra_ms:.1f} | {cell} | "
                  + " | ".join(cols) + " |", flush=True)


if __name__ == "__main__":
    main()
