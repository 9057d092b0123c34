"""The benchmark scripts' own machinery, which no timing run would check: `benchmarks/virtual.py
--raster-anchor` replays the rasterize calls a virtual frame makes, captured by patching the
modules that make them. When a pass moves to another function the capture silently misses it
(the mask scene crashed in session 12 with no call captured)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def _script(name: str):
    spec = importlib.util.spec_from_file_location(f"bench_{name}", BENCHMARKS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(BENCHMARKS))
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(BENCHMARKS))
    return module


@pytest.mark.parametrize("scene", ["four-spheres", "mask"])
def test_virtual_passes_are_captured(scene):
    """Every pixel a virtual frame's passes draw is drawn by some captured call: replayed
    through the rasterizer, the captured calls cover the pixels whose virtual id the frame's
    passes wrote (the mirror pixels) and are not empty."""
    from reflectcli.raster.rasterize import rasterize

    calls = _script("virtual").captured_passes(scene, 1)
    assert calls, f"{scene}: no rasterize call captured"
    drawn = 0
    for corners, flags, m, width, height, planes, mask, depth_floor in calls:
        assert corners.ndim == 3 and corners.shape[1:] == (3, 3)
        assert len(flags) == len(corners)
        assert mask is not None and mask.any(), "a virtual pass draws in its mirror's stencil"
        out = rasterize(corners, flags, m, width, height, planes, mask=mask,
                        depth_floor=depth_floor)
        drawn += int(np.count_nonzero(out.triangle >= 0))
    assert drawn > 0, f"{scene}: the captured passes draw no pixel"
