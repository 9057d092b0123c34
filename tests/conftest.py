"""Shared fixtures: shipped scenes, and rendering a scene frame in-process."""

from __future__ import annotations

import os
from pathlib import Path

import numba
import numpy as np
import pytest

from reflectcli import api, openmp, warmup

# pytest-xdist's workers share the cores: their idle OpenMP threads sleep at once (the suite
# took 120 s with each worker's spinning 0.7 ms after every parallel loop, 93 s without)
if os.environ.get("PYTEST_XDIST_WORKER") and openmp.defaulted:
    openmp.no_spin()

# the compile notice (reflectcli/warmup.py) is for a person waiting: tests that hold a
# command's stderr to one line (in-process or in subprocesses, which inherit this) would
# read it whenever a kernel compiles cold
os.environ[warmup.NO_NOTICE] = "1"

# `make coverage` runs the kernels as Python (NUMBA_DISABLE_JIT=1). A few tests hold the
# compiled kernel to a result only compiled code gives: interpreted NumPy 2 keeps some
# float32 arithmetic in float32 where the compiled kernel widens to float64 (texel weights,
# ties in _pick, the reflector grid's coordinates), and the Embree packet kernel cannot call
# into the library.
compiled_only = pytest.mark.skipif(numba.config.DISABLE_JIT,
                                   reason="holds the compiled kernel; numba's JIT is off")

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def render_frame(scene: str | Path, technique: str | None = None, frame: int = 0,
                 overrides: tuple[str, ...] = (), **options):
    """Render one frame of a scene file in-process, maps kept in memory: (Frame, Scene)."""
    opened = open_scene(scene, technique, overrides, **options)
    return opened.render_frame(frame), opened.scene


def open_scene(scene: str | Path, technique: str | None = None,
               overrides: tuple[str, ...] | list[str] = (), **options) -> api.OpenedScene:
    """A shipped scene by name (or any scene file) opened through the api; maps in memory
    unless `cache` says otherwise."""
    path = Path(scene) if Path(scene).suffix else SCENES / f"{scene}.toml"
    options.setdefault("cache", False)
    return api.open_scene(str(path), overrides=list(overrides), technique=technique, **options)


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """PSNR in dB for linear images with peak 1 over the given pixels (N, 3)."""
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(1.0 / mse)


@pytest.fixture
def render():
    return render_frame


@pytest.fixture
def scenes_dir() -> Path:
    return SCENES


def projection_of(sx, sy, z, mh, mw, shape):
    """A Projection as project_map fills it, from given screen positions and depths."""
    h, w = shape
    from reflectcli.maps.warp import Projection

    proj = Projection.empty(mh, mw)
    proj.sx[:], proj.sy[:], proj.z[:] = sx, sy, z
    ok = ~np.isnan(sx)
    px = np.floor(np.where(ok, sx, 0)).astype(np.int64)
    py = np.floor(np.where(ok, sy, 0)).astype(np.int64)
    on = ok & (px >= 0) & (px < w) & (py >= 0) & (py < h)
    proj.pix[:] = np.where(on, py * w + px, -1)
    with np.errstate(invalid="ignore"):
        ex = sx - np.floor(sx) - np.float32(0.5)
        ey = sy - np.floor(sy) - np.float32(0.5)
        proj.d[:] = ex * ex + ey * ey
    rows, okr = py.reshape(mh, mw), ok.reshape(mh, mw)
    proj.row_lo[:] = np.where(okr, rows, 1 << 40).min(axis=1)
    hi = np.where(okr, rows, np.iinfo(np.int64).min).max(axis=1)
    proj.row_hi[:] = np.where(okr.any(axis=1), hi, -1)
    proj.count[:] = okr.sum(axis=1)
    return proj
