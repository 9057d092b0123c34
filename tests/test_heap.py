"""The frames' working memory is faulted in once, in prepare (heap.py)."""

from __future__ import annotations

import platform

import pytest
from conftest import open_scene

from reflectcli import heap


def test_reserve_touches_whole_blocks_up_to_the_cap():
    if platform.libc_ver()[0] != "glibc":
        pytest.skip("the allocator is told to keep freed memory only on glibc")
    assert heap.reserve(0) == 0
    assert heap.reserve(1) == 16 << 20
    assert heap.reserve(40 << 20) == 48 << 20
    assert heap.reserve(10 * heap.MAX_RESERVE) == heap.MAX_RESERVE


def test_prepare_reserves_the_frames_working_memory_once(monkeypatch):
    asked = []
    monkeypatch.setattr(heap, "reserve", lambda nbytes: asked.append(nbytes) or nbytes)
    scene = open_scene("cylinder", technique="raster",
                       overrides=["camera.width=40", "camera.height=30"])
    scene.prepare()
    scene.prepare()
    scene.render_frame(0)
    assert len(asked) == 1 and asked[0] >= 40 * 30 * 3 * 8  # at least an rgb float64 image
