"""Environment-map capture time per map and lookup time per frame against resolution, and
PSNR against raytrace for plain and box-projected lookups, measured in one run.

    .venv/bin/python benchmarks/envmap.py
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

from reflectcli import api
from reflectcli.bench.metrics import image_metrics

ROOT = Path(__file__).resolve().parents[1]


def open_scene(name: str, technique: str, overrides: list[str]) -> api.OpenedScene:
    """A shipped scene, maps kept in memory (every capture is a real one)."""
    return api.open_scene(str(ROOT / "scenes" / f"{name}.toml"), technique=technique,
                          overrides=overrides, threads=2, cache=False)


def mirror_psnr(frame, ref) -> float:
    """PSNR over the pixels that are mirror in both frames."""
    return image_metrics(frame.rgb, ref.rgb, ref.mirror_mask & frame.mirror_mask)["psnr"]


def main() -> None:
    for res in (128, 256, 512, 1024):
        scene = open_scene("teapot-box", "envmap", [f"technique.resolution={res}"])
        scene.precompute()  # warm-up
        captures = []
        for _ in range(3):
            t = time.perf_counter()
            records = scene.precompute()
            captures.append(time.perf_counter() - t)
        scene.render_frame(0)
        lookups = [scene.render_frame(0).timings["lookup"] for _ in range(7)]
        print(f"resolution {res:5d}: capture {1e3 * statistics.median(captures):7.1f} ms per "
              f"map ({len(records)} map), lookup {1e3 * statistics.median(lookups):6.2f} ms "
              f"per frame")
    for scene_name in ("teapot-box", "four-spheres"):
        ref = open_scene(scene_name, "raytrace", ["technique.max_depth=1"]).render_frame(0)
        for parallax in ("none", "box"):
            out = open_scene(scene_name, "envmap", [f'technique.parallax="{parallax}"'])
            print(f"{scene_name} parallax {parallax}: PSNR over mirrors "
                  f"{mirror_psnr(out.render_frame(0), ref):.1f} dB")


if __name__ == "__main__":
    main()
