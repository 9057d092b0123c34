"""Environment-map capture time per map and lookup time per frame against resolution, and
PSNR against raytrace for plain and box-projected lookups, measured in one run.

    .venv/bin/python benchmarks/envmap.py
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from conftest import psnr, render_frame  # noqa: E402

from reflectcli.camera import camera_from_config  # noqa: E402
from reflectcli.loading import load_config  # noqa: E402
from reflectcli.scene.build import build_scene  # noqa: E402
from reflectcli.techniques.envmap.technique import Envmap  # noqa: E402


def main() -> None:
    path = str(ROOT / "scenes" / "teapot-box.toml")
    for res in (128, 256, 512, 1024):
        cfg, _ = load_config(path, [f"technique.resolution={res}"], "envmap")
        scene = build_scene(cfg, path)
        tech = Envmap(cfg.technique, 2)
        tech.precompute(scene)  # warm-up
        captures = []
        for _ in range(3):
            t = time.perf_counter()
            records = tech.precompute(scene)
            captures.append(time.perf_counter() - t)
        state = tech.prepare(scene)
        cam = camera_from_config(cfg.camera, 0)
        tech.render(state, 0, cam)
        lookups = [tech.render(state, 0, cam).timings["lookup"] for _ in range(7)]
        print(f"resolution {res:5d}: capture {1e3 * statistics.median(captures):7.1f} ms per "
              f"map ({len(records)} map), lookup {1e3 * statistics.median(lookups):6.2f} ms "
              f"per frame")
    for scene_name in ("teapot-box", "four-spheres"):
        ref, _ = render_frame(scene_name, "raytrace", 0, ("technique.max_depth=1",))
        for parallax in ("none", "box"):
            out, _ = render_frame(scene_name, "envmap", 0, (f'technique.parallax="{parallax}"',))
            m = ref.mirror_mask & out.mirror_mask
            print(f"{scene_name} parallax {parallax}: PSNR over mirrors "
                  f"{psnr(out.rgb[m], ref.rgb[m]):.1f} dB")


if __name__ == "__main__":
    main()
