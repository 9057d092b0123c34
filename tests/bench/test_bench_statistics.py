"""Bench statistics without rendering: timing medians and warnings, the Pareto front, report
rows with every override, plot lines that never join scenes or other parameter values."""

from __future__ import annotations

import math

import pytest

from reflectcli.bench.report import pareto_front, report_markdown
from reflectcli.bench.runner import timing_samples, timing_stats


def test_timing_leaves_out_warmup_and_warns_when_short():
    samples = [9.7, 0.9, 0.8, 1.0]  # a first render paying for first-frame caches
    t = timing_stats(samples, warmup=1)
    assert t["frame_ms_median"] == pytest.approx(900.0)
    assert t["frame_ms_p25"] == pytest.approx(850.0) and t["frame_ms_p75"] == pytest.approx(950.0)
    assert t["first_frame_ms"] == pytest.approx(9700.0)
    assert t["timed_frames"] == 3 and t["timing_warning"] == ""
    short = timing_stats([9.7], warmup=0)
    assert short["frame_ms_median"] == pytest.approx(9700.0)
    assert "0 warm-up" in short["timing_warning"] and "1 timed" in short["timing_warning"]
    assert "2 timed" in timing_stats([1.0, 2.0, 3.0], warmup=1)["timing_warning"]


def test_repeats_are_samples_in_render_order():
    log = [{"frame_seconds": 5.0, "repeat_seconds": [5.0, 1.0, 1.1]},
           {"frame_seconds": 1.2}]
    assert timing_samples(log) == [5.0, 1.0, 1.1, 1.2]


def _row(technique, ms, flip, overrides=(), scene="s", psnr=20.0, triangles=100):
    return {"run": f"{technique}{ms}", "scene": scene, "technique": technique,
            "overrides": list(overrides), "sweep": {}, "frame_ms_median": ms,
            "frame_ms_p25": ms, "frame_ms_p75": ms, "timing_warning": "",
            "reference_ms_median": 10.0, "psnr_mirror": psnr, "psnr_image": psnr,
            "flip_mirror": flip, "hole_fraction": 0.0, "triangles": triangles,
            "cpu": "cpu", "threads": 2, "versions": {"reflect": "0"}}


def test_pareto_front():
    rows = [_row("a", 1.0, 0.5), _row("b", 2.0, 0.6), _row("c", 3.0, 0.2),
            _row("d", 5.0, 0.2), _row("e", 8.0, 0.0), _row("f", 9.0, math.nan)]
    assert [r["technique"] for r in pareto_front(rows)] == ["a", "c", "e"]


def test_report_rows_show_every_override_and_warnings():
    rows = [_row("virtual", 9.0, 0.3, ['technique.method="explosion"', "mirrors.s.segments=64"]),
            _row("virtual", 8.0, 0.2)]
    rows[0]["timing_warning"] = "0 warm-up (want >= 1 warm-up, >= 3 timed)"
    text = report_markdown("b", rows)
    assert 'method="explosion", mirrors.s.segments=64' in text
    assert "**warning: 0 warm-up" in text
    assert "| virtual | defaults |" in text
    # the two rows have different scene overrides: two fronts, one per scene variant
    assert text.count("### Quality at equal time budget") == 2


def test_ratios_from_a_warned_side_are_marked():
    """A ratio is only as sound as its worse side: the warned row's own ratios, a ratio to
    a warned rerender row and a ratio to a warned reference all carry a *."""
    rows = [_row("rerender", 4.0, 0.0), _row("virtual", 8.0, 0.2), _row("envmap", 2.0, 0.5)]
    rows[1]["timing_warning"] = "0 warm-up, 1 timed (want >= 1 warm-up, >= 3 timed)"
    rows[2]["reference_timing_warning"] = "1 timed (want >= 1 warm-up, >= 3 timed)"
    lines = {line.split(" | ")[0]: line.split(" | ") for line in
             report_markdown("b", rows).splitlines() if line.startswith("| ")}
    # x rerender, x raytrace: the 16th and 17th columns
    assert lines["| rerender"][15:17] == ["1.00", "0.40"]
    assert lines["| virtual"][15:17] == ["2.00*", "0.80*"]
    assert lines["| envmap"][15:17] == ["0.50", "0.20*"]
    rows[0]["timing_warning"] = "1 timed"
    lines = {line.split(" | ")[0]: line.split(" | ") for line in
             report_markdown("b", rows).splitlines() if line.startswith("| ")}
    assert lines["| envmap"][15:17] == ["0.50*", "0.20*"]
    # two rerender rows on one scene (a sweep): the ratio and its mark are the one at
    # rerender's defaults, whichever comes last; two at the same settings: no ratio
    other = _row("rerender", 8.0, 0.0)
    swept = _row("rerender", 16.0, 0.0, ['technique.clip="none"'])

    def envmap_ratio(rows):
        (line,) = [line.split(" | ") for line in report_markdown("b", rows).splitlines()
                   if line.startswith("| envmap | ")]
        return line[15]

    assert envmap_ratio([rows[2], other, swept]) == "0.25"
    assert envmap_ratio([rows[2], swept, other]) == "0.25"
    assert envmap_ratio([rows[0], rows[2], other]) == "-"


def _per_frame(row, frames):
    row["per_frame"] = [{"frame": f} for f in frames]
    return row


def test_ratio_to_rerender_needs_the_same_frames_threads_and_cpu():
    """`x rerender` sets two runs' medians against each other only when they timed the
    same frames (two [[runs]] groups may time other frames of one scene) at the same thread
    count on the same CPU (a resumed row may come from another bench run)."""
    rerender = _per_frame(_row("rerender", 4.0, 0.0), [0, 1, 2])
    envmap = _per_frame(_row("envmap", 2.0, 0.5), [0, 1, 2])

    def ratio(rows):
        (line,) = [line.split(" | ") for line in report_markdown("b", rows).splitlines()
                   if line.startswith("| envmap | ")]
        return line[15]

    assert ratio([rerender, envmap]) == "0.50"
    assert ratio([rerender, _per_frame(dict(envmap), [3, 4, 5])]) == "-"
    assert ratio([rerender, {**envmap, "threads": 1}]) == "0.50*"
    assert ratio([rerender, {**envmap, "cpu": "other"}]) == "0.50*"
    # the machine line names both thread counts, not the first row's alone
    text = report_markdown("b", [rerender, {**envmap, "threads": 1}])
    assert "cpu, 2 threads (1 of 2 runs); cpu, 1 threads (1 of 2 runs)" in text


def test_report_states_the_sample_count_and_the_percentile_method():
    """A p25-p75 of one or two renders is no spread: each frame time says how many renders
    it is of, and the header how the percentiles are taken."""
    row = _row("envmap", 2.0, 0.5)
    row.update(timed_frames=2, frame_ms_p25=1.75, frame_ms_p75=2.25,
               timing_warning="2 timed (want >= 1 warm-up, >= 3 timed)")
    text = report_markdown("b", [row])
    assert "| 2.0 (1.8-2.2, n=2) **warning: 2 timed" in text
    assert "frame ms median (p25-p75, n)" in text
    assert "linear interpolation" in text and "n = 2" in text
    assert "Incomplete" not in text
    assert "**Incomplete: 1 of 3 runs finished**" in report_markdown("b", [row], total=3)


def test_reference_timed_elsewhere_warns():
    """The `x raytrace` ratio's other side: a reference timed at another thread count or on
    another CPU (a Dask worker elsewhere) is warned, so the ratio is marked."""
    from reflectcli.bench.runner import _reference_timing

    stats = timing_stats([9.0, 1.0, 1.0, 1.0], warmup=1)
    same = _reference_timing(stats, [{"threads": 2, "cpu": "c"}], {"threads": 2, "cpu": "c"})
    assert same["reference_timing_warning"] == ""
    other = _reference_timing(stats, [{"threads": 2, "cpu": "c"}], {"threads": 1, "cpu": "c"})
    assert "reference timed at threads 2, this run at 1" in other["reference_timing_warning"]
    cpu = _reference_timing(stats, [{"threads": 2, "cpu": "d"}], {"threads": 2, "cpu": "c"})
    assert "CPU d" in cpu["reference_timing_warning"]


def test_plot_lines_never_join_scenes_or_other_values():
    pytest.importorskip("matplotlib")
    from reflectcli.bench.plots import _lines

    rows = [_row("virtual", 1, 0.1, ["technique.n=1", 'technique.method="a"']),
            _row("virtual", 2, 0.1, ["technique.n=2", 'technique.method="a"']),
            _row("virtual", 3, 0.1, ["technique.n=1", 'technique.method="b"']),
            _row("virtual", 4, 0.1, ["technique.n=1", 'technique.method="a"'], scene="t")]
    groups = _lines(rows, {"technique.n"})
    assert sorted(len(g) for g in groups.values()) == [1, 1, 2]
    assert all(len({r["scene"] for r in g}) == 1 for g in groups.values())


def test_render_repeats_write_the_first_render_and_log_every_time(tmp_path):
    from pathlib import Path

    from reflectcli import api
    from reflectcli.output.exr import read_exr
    from reflectcli.output.log import read_jsonl

    scene = str(Path(__file__).resolve().parents[2] / "scenes" / "teapot-box.toml")
    small = ["camera.width=32", "camera.height=24"]
    once = api.render(scene, out=str(tmp_path / "a"), frames="0", technique="rerender",
                      overrides=small)
    thrice = api.render(scene, out=str(tmp_path / "b"), frames="0", technique="rerender",
                        overrides=small, repeats=3)
    log = read_jsonl(str(Path(thrice.folder) / "timings.jsonl"))
    assert len(log) == 1 and len(log[0]["repeat_seconds"]) == 3
    assert log[0]["repeat_seconds"][0] == log[0]["frame_seconds"]
    assert "repeat_seconds" not in read_jsonl(str(Path(once.folder) / "timings.jsonl"))[0]
    a, _ = read_exr(once.written[0])
    b, _ = read_exr(thrice.written[0])
    assert all((a[c] == b[c]).all() for c in a)


def test_repeats_write_the_first_render_not_a_later_one(tmp_path):
    """Each render of the frame is told apart by its colour, so writing any repeat but the
    first would show (a real technique gives the same pixels at every repeat)."""
    from dataclasses import replace
    from pathlib import Path

    from reflectcli import api
    from reflectcli.output.exr import read_exr

    scene = str(Path(__file__).resolve().parents[2] / "scenes" / "teapot-box.toml")
    opened = api.open_scene(scene, technique="raster", threads=1,
                            overrides=["camera.width=16", "camera.height=12"])
    technique_render = opened.technique.render
    renders = []

    def numbered(*args):
        frame = technique_render(*args)
        renders.append(len(renders) + 1)
        return replace(frame, rgb=frame.rgb * 0 + len(renders))

    opened.technique.render = numbered
    result = opened.write_frames([0], out=str(tmp_path), repeats=3)
    assert renders == [1, 2, 3]
    channels, _ = read_exr(result.written[0])
    assert (channels["R"] == 1).all()


def test_report_says_when_the_machine_was_busy():
    """Runs timed while other work wanted the cores (a 2-core machine at load 4) have frame
    times that include waiting for them: a smoke bench here read raster at 21.9 ms and
    x rerender 61 under load, 0.5 ms and 1.7 on an idle machine."""
    from reflectcli.bench.report import busy_rows

    quiet = {**_row("envmap", 2.0, 0.5), "load_1min": [0.4, 1.1], "cores": 2}
    busy = {**_row("raster", 20.0, 0.9), "load_1min": [1.5, 3.7], "cores": 2}
    own = {**_row("virtual", 20.0, 0.9), "load_1min": [2.3, 2.9], "cores": 2}  # its threads
    assert busy_rows([quiet, busy, own]) == [busy]
    text = report_markdown("b", [quiet])
    assert "Load average (1 min) around the runs: 0.4-1.1 on 2 cores." in text
    assert "busy machine" not in text
    assert "**1 of 2 runs were timed on a busy machine" in report_markdown("b", [quiet, busy])
    assert "Load average" not in report_markdown("b", [_row("envmap", 2.0, 0.5)])
