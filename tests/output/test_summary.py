"""timings-summary.json: per-stage medians with their spread after the warm-up render."""

from __future__ import annotations

import json
import os

import pytest
from conftest import SCENES, open_scene

from reflectcli.output.log import read_jsonl
from reflectcli.output.names import SUMMARY_NAME
from reflectcli.output.summary import timings_summary

SMALL = ("camera.width=64", "camera.height=48", "camera.path.frames=4")


def _files(folder: str) -> dict[str, bytes]:
    return {n: open(os.path.join(folder, n), "rb").read()
            for n in sorted(os.listdir(folder)) if n.endswith((".exr", ".png"))}


def test_timings_summary_after_warmup(tmp_path):
    opened = open_scene("teapot-box", "rerender", SMALL, threads=1)
    result = opened.write_frames(opened.frames(), out=str(tmp_path))
    with open(os.path.join(result.folder, SUMMARY_NAME)) as f:
        summary = json.load(f)
    assert summary["frames"] == [0, 1, 2, 3] and summary["warmup_renders"] == 1
    assert summary["timed_renders"] == 3 and summary["warning"] == ""
    frame = summary["frame"]
    assert frame["p25_ms"] <= frame["median_ms"] <= frame["p75_ms"]
    rows = read_jsonl(os.path.join(result.folder, "timings.jsonl"))
    assert set(summary["stages"]) == set(rows[1]["stages"])
    times = sorted(1e3 * r["frame_seconds"] for r in rows[1:])
    assert frame["median_ms"] == pytest.approx(times[1])
    writes = sorted(1e3 * r["write_seconds"] for r in rows)  # every frame's write
    assert summary["write"]["median_ms"] == pytest.approx((writes[1] + writes[2]) / 2)


def test_timings_summary_warns_on_one_cold_frame():
    row = {"scene": "s", "technique": "t", "frame": 0, "frame_seconds": 0.5,
           "stages": {"a": 0.25}, "write_seconds": 0.1}
    summary = timings_summary([row])
    assert "cold" in summary["warning"] and summary["timed_renders"] == 1
    assert summary["frame"]["median_ms"] == 500.0
    repeated = timings_summary([{**row, "repeat_seconds": [0.5, 0.2, 0.3, 0.4]}])
    assert repeated["warning"] == "" and repeated["frame"]["median_ms"] == pytest.approx(300)


def test_a_still_frames_stages_come_from_its_timed_repeats():
    """A still scene's one log row holds its first render's stages (the warm-up: JIT, first
    touches) in `stages`; the summary's stages are the repeats after it, as its frame time
    is. (They were that one warm-up render's: a bench of a still scene showed seconds of
    compilation as a stage's median.)"""
    row = {"scene": "s", "technique": "t", "frame": 0, "frame_seconds": 5.0,
           "stages": {"a": 4.0, "b": 1.0},
           "repeat_seconds": [5.0, 0.3, 0.2, 0.4],
           "repeat_stages": [{"a": 4.0, "b": 1.0}, {"a": 0.1, "b": 0.2},
                             {"a": 0.05, "b": 0.15}, {"a": 0.2, "b": 0.2}]}
    summary = timings_summary([row])
    assert summary["timed_renders"] == 3 and summary["warning"] == ""
    assert summary["stages"]["a"]["median_ms"] == pytest.approx(100.0)
    assert summary["stages"]["a"]["n"] == summary["timed_renders"]  # every spread says its n
    assert summary["stages"]["b"]["median_ms"] == pytest.approx(200.0)
    assert summary["stages"]["a"]["p75_ms"] < 4000.0


def test_render_repeats_log_each_renders_stages(tmp_path):
    from reflectcli import api

    result = api.render(str(SCENES / "teapot-box.toml"), out=str(tmp_path), frames="0",
                        technique="rerender", overrides=list(SMALL[:2]), threads=1, repeats=4)
    (row,) = read_jsonl(os.path.join(result.folder, "timings.jsonl"))
    assert len(row["repeat_stages"]) == 4 and row["repeat_stages"][0] == row["stages"]
    assert all(set(s) == set(row["stages"]) for s in row["repeat_stages"])
    with open(os.path.join(result.folder, SUMMARY_NAME)) as f:
        summary = json.load(f)
    timed = sorted(1e3 * s["rasterize"] for s in row["repeat_stages"][1:])
    assert summary["stages"]["rasterize"]["median_ms"] == pytest.approx(timed[1])


@pytest.mark.parametrize("technique,extra", [
    ("envmap", ()),
    ("dprm", ("technique.maps.count=1", "technique.maps.per_frame=1",
               "technique.maps.resolution=32")),
    ("distmap", ("technique.resolution=32",)),
])
def test_map_capture_is_prepare_work_not_a_frame_stage(tmp_path, technique, extra):
    """A map technique's one-time capture is timed in prepare and logged apart
    (`precompute_seconds`): no frame's stages, frame 0's included, carry it."""
    opened = open_scene("teapot-box", technique, SMALL[:2] + ("camera.path.frames=2",) + extra,
                        threads=1)
    result = opened.write_frames(opened.frames(), out=str(tmp_path))
    rows = read_jsonl(os.path.join(result.folder, "timings.jsonl"))
    assert [r["frame"] for r in rows] == [0, 1]
    for row in rows:
        assert "precompute" not in row["stages"]
        assert 0.0 < row["precompute_seconds"] <= row["prepare_seconds"]
