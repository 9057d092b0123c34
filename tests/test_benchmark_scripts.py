"""The benchmark scripts' own machinery, which no timing run would check: `benchmarks/virtual.py
--raster-anchor` replays the rasterize calls a virtual frame makes, captured by patching the
modules that make them. When a pass moves to another function the capture silently misses it
(the mask scene crashed in session 12 with no call captured)."""

from __future__ import annotations

import importlib.util
import re
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


def test_versions_loads_another_version_under_its_own_name(tmp_path):
    """benchmarks/versions.py's copy of another version: its package under another name,
    every mention of reflectcli in its code renamed (its technique registry, resources and
    absolute imports included), importable beside this one without touching it; kept for
    the next run. Its report and the frames' bit-for-bit check, on made-up numbers."""
    import importlib

    versions = _script("versions")
    cache = tmp_path / "cache"
    name = versions.other_package(str(BENCHMARKS.parent), cache)
    assert name.startswith("reflectcli_") and (cache / name / "api.py").is_file()
    for path in (cache / name).rglob("*.py"):
        assert re.search(r"\breflectcli\b", path.read_text("utf-8")) is None, path
    assert versions.other_package(str(BENCHMARKS.parent), cache) == name  # kept
    sys.path.insert(0, str(cache))
    try:
        other = importlib.import_module(name + ".techniques.registry")
        import reflectcli.techniques.registry as ours

        assert other is not ours and other.__name__.startswith(name)
        assert callable(importlib.import_module(name + ".api").open_scene)
    finally:
        sys.path.remove(str(cache))
    a = {"rgb": np.zeros((2, 2, 3), np.float32), "depth": np.ones((2, 2), np.float32)}
    b = {k: v.copy() for k, v in a.items()}
    assert versions.same_channels(a, b)
    b["depth"][0, 0] = np.nextafter(np.float32(1), np.float32(2))
    assert not versions.same_channels(a, b)
    text = versions.report({"new": [0.9, 1.0, 1.1, 1.0], "old": [1.0, 1.0, 1.2, 1.1],
                           "same": True})
    assert "median of the rounds' ratios 0.913" in text and "the same" in text
