"""Distance-map capture time per map and search time per frame at 256 and 512 texels per
face, for layers 1 and 4, as medians after a warm-up (maps kept in memory: every capture
is a real one).

    .venv/bin/python benchmarks/distmap.py [scene]      # default: l-room (one ball)
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

from reflectcli import api

ROOT = Path(__file__).resolve().parents[1]


def main(scene_name: str = "l-room") -> None:
    for res in (256, 512):
        for layers in (1, 4):
            scene = api.open_scene(str(ROOT / "scenes" / f"{scene_name}.toml"),
                                   technique="distmap", threads=2, cache=False,
                                   overrides=[f"technique.resolution={res}",
                                              f"technique.layers={layers}"])
            scene.precompute()  # warm-up (numba compile, caches)
            captures = []
            for _ in range(3):
                t = time.perf_counter()
                records = scene.precompute()
                captures.append((time.perf_counter() - t) / len(records))
            scene.render_frame(0)
            searches = [scene.render_frame(0).timings["search"] for _ in range(5)]
            print(f"{scene_name} resolution {res:4d} layers {layers}: capture "
                  f"{1e3 * statistics.median(captures):7.1f} ms per map, search "
                  f"{1e3 * statistics.median(searches):6.1f} ms per frame", flush=True)


if __name__ == "__main__":
    main(*sys.argv[1:])
