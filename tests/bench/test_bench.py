"""The bench end to end: outputs, resume, processes and a Dask cluster give the same rows."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from reflectcli.bench.report import CSV_COLUMNS
from reflectcli.bench.runner import run_bench
from reflectcli.cli import cli
from reflectcli.output.log import read_jsonl

ROOT = Path(__file__).resolve().parents[2]
TIMING = {"frame_ms_median", "frame_ms_p25", "frame_ms_p75", "reference_ms_median",
          "precompute_seconds", "prepare_seconds", "first_frame_ms", "numba_compile_seconds",
          "images", "reference_images",
          "capture_ms_per_frame", "load_1min"}


def _bench_file(tmp_path, name="t"):
    path = tmp_path / f"{name}.toml"
    scenes = ROOT / "scenes"
    path.write_text(f"""
[bench]
name = "{name}"
frames = "0:2"
warmup = 1
out = "out-{name}"
plots = true

[[runs]]
scenes = ["{scenes / 'teapot-box.toml'}"]
techniques = ["rerender", "envmap"]
set = ["camera.width=48", "camera.height=36"]

[[runs]]
scenes = ["{scenes / 'teapot-box.toml'}"]
techniques = ["dprm"]
set = ["camera.width=48", "camera.height=36", "technique.maps.count=1",
       "technique.maps.per_frame=1", 'technique.reconstruct="color"']
[runs.sweep]
"technique.maps.resolution" = [16, 32]
""")
    return path


def _stable(rows):
    return [{k: v for k, v in r.items() if k not in TIMING} for r in rows]


def test_bench_writes_every_output(tmp_path):
    result = CliRunner().invoke(cli, ["bench", str(_bench_file(tmp_path))])
    assert result.exit_code == 0, result.output
    out = tmp_path / "out-t"
    rows = read_jsonl(str(out / "results.jsonl"))
    assert len(rows) == 4 and len({r["run"] for r in rows}) == 4
    with open(out / "results.csv") as f:
        table = list(csv.reader(f))
    assert table[0] == CSV_COLUMNS and len(table) == 5
    report = (out / "report.md").read_text()
    assert "## teapot-box" in report and report.count("| dprm |") == 2
    for png in ("contact-teapot-box.png", "error-vs-maps.resolution.png"):
        assert (out / png).stat().st_size > 1000
    rerender = next(r for r in rows if r["technique"] == "rerender")
    assert rerender["psnr_mirror"] > 60  # rerender is exact against the ray tracer
    dprm = sorted((r for r in rows if r["technique"] == "dprm"),
                  key=lambda r: r["sweep"]["technique.maps.resolution"])
    assert dprm[0]["hole_fraction"] > dprm[1]["hole_fraction"]  # denser maps, fewer holes
    for r in rows:
        assert r["versions"]["reflect"] and r["cpu"] and r["threads"] >= 1
        # two frames after one warm-up: each rendered twice so that 3 renders are timed
        assert r["timed_frames"] == 3 and r["frames"] == 2 and r["repeats"] == 2


def test_resumed_bench_equals_uninterrupted(tmp_path):
    path = _bench_file(tmp_path)
    full = run_bench(str(path))
    rows_file = tmp_path / "out-t" / "results.jsonl"
    lines = rows_file.read_text().splitlines()
    rows_file.write_text("\n".join(lines[:2]) + "\n")  # as if stopped after two runs
    resumed = run_bench(str(path), resume=True)
    assert resumed.ran == 2 and resumed.skipped == 2
    assert _stable(resumed.rows) == _stable(full.rows)
    assert len(read_jsonl(str(rows_file))) == 4


def test_local_processes_give_the_same_rows(tmp_path):
    serial = run_bench(str(_bench_file(tmp_path, "s")))
    parallel = run_bench(str(_bench_file(tmp_path, "p")), workers=2)
    strip = [{k: v for k, v in r.items() if k != "run"} for r in _stable(serial.rows)]
    assert strip == [{k: v for k, v in r.items() if k != "run"} for r in _stable(parallel.rows)]


def test_dask_cluster_gives_the_same_rows(tmp_path):
    distributed = pytest.importorskip("distributed")
    import dask
    serial = run_bench(str(_bench_file(tmp_path, "s")))
    scratch = str(tmp_path / "dask")  # not the shared temp folder's dask-scratch-space
    with dask.config.set({"temporary-directory": scratch}), \
            distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                     dashboard_address=None, local_directory=scratch) as cluster:
        remote = run_bench(str(_bench_file(tmp_path, "d")), scheduler=cluster.scheduler_address)
    strip = [{k: v for k, v in r.items() if k != "run"} for r in _stable(serial.rows)]
    assert strip == [{k: v for k, v in r.items() if k != "run"} for r in _stable(remote.rows)]


def test_bad_bench_file(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('[bench]\nname = "bad"\n[[runs]]\nscenes = ["nope.toml"]\n'
                    'techniques = ["raytrace"]\n')
    result = CliRunner().invoke(cli, ["bench", str(path)])
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert "bad.toml" in result.output and "nope.toml" in result.output


def test_compare_command(tmp_path):
    runner = CliRunner()
    scene = str(ROOT / "scenes" / "teapot-box.toml")
    for tech in ("raytrace", "rerender"):
        r = runner.invoke(cli, ["render", scene, "--technique", tech, "--frames", "0",
                                "--out", str(tmp_path), "--set", "camera.width=64",
                                "--set", "camera.height=48", "--set", "technique.max_depth=1"])
        assert r.exit_code == 0, r.output
    a = tmp_path / "teapot-box" / "raytrace" / "frame_0000.exr"
    b = tmp_path / "teapot-box" / "rerender" / "frame_0000.exr"
    r = runner.invoke(cli, ["compare", str(a), str(b), "--mask-channel", "mirror"])
    assert r.exit_code == 0 and "psnr      inf dB" in r.output and "mirror > 0" in r.output
    r = runner.invoke(cli, ["compare", str(a), str(b), "--mask-channel", "nope"])
    assert r.exit_code == 2 and "channels: missing nope" in r.output


def test_smoke_preset(tmp_path, monkeypatch):
    """configs/bench/smoke.toml, the CI matrix: every output well formed (not timings)."""
    monkeypatch.chdir(tmp_path)
    result = run_bench(str(ROOT / "configs" / "bench" / "smoke.toml"))
    out = Path(result.out)
    rows = read_jsonl(str(out / "results.jsonl"))
    assert len(rows) == result.ran == 10
    with open(out / "results.csv") as f:
        table = list(csv.DictReader(f))
    assert len(table) == 10 and set(table[0]) == set(CSV_COLUMNS)
    for row in table:
        assert float(row["frame_ms_median"]) > 0 and row["technique"] and row["scene"]
        assert row["psnr_mirror"] != "" and 0.0 <= float(row["hole_fraction"]) <= 1.0
    assert (out / "report.md").read_text().startswith("# Bench `smoke`")
    assert {p.name for p in out.glob("contact-*.png")} == {"contact-teapot-box.png",
                                                         "contact-four-spheres.png"}


@pytest.mark.parametrize("preset", ["paper-dprm", "paper-curved", "scaling"])
def test_presets_validate(preset):
    from reflectcli.bench.runner import load_bench

    plan = load_bench(str(ROOT / "configs" / "bench" / f"{preset}.toml"))
    assert len(plan.jobs) >= 8


def test_edited_scene_gets_a_new_reference(tmp_path):
    scene = tmp_path / "box.toml"
    scene.write_text((ROOT / "scenes" / "teapot-box.toml").read_text())
    bench = tmp_path / "b.toml"
    bench.write_text(f"""
[bench]
name = "b"
frames = "0"
warmup = 0
out = "out-b"
plots = false

[[runs]]
scenes = ["{scene}"]
techniques = ["rerender"]
set = ["camera.width=32", "camera.height=24"]
""")
    first = run_bench(str(bench))
    scene.write_text(scene.read_text().replace("color = [0.8, 0.1, 0.1]",
                                               "color = [0.1, 0.8, 0.1]"))
    second = run_bench(str(bench))
    refs = list((tmp_path / "out-b" / "references").iterdir())
    assert len(refs) == 2  # the old reference is not reused for the edited scene
    assert first.rows[0]["psnr_mirror"] > 60 and second.rows[0]["psnr_mirror"] > 60


def test_holes_count_only_where_the_reference_reflects_geometry():
    """A technique's raw holes include mirror pixels whose reflection is the background
    (open scenes: 46-64% 'holes' while looking complete); the bench's hole_fraction counts
    only the pixels where the reference's reflected ray meets geometry."""
    from reflectcli.bench.runner import hole_fractions

    mirror = np.zeros((4, 4), bool)
    mirror[:, :2] = True  # 8 mirror pixels
    hit = np.zeros((4, 4), np.float32)
    hit[:2, :2] = 1.0  # 4 of them reflect geometry, 4 the sky
    holes = np.zeros((4, 4), np.float32)
    holes[:, 0] = 1.0  # 4 holes: 2 over geometry, 2 over the sky
    row = {"unreached_fraction": 0.5}
    got = hole_fractions({"holes": holes}, {"reflected_hit": hit}, mirror, row)
    assert got == {"hole_fraction": 0.5, "unreached_fraction": 0.5}
    holes[:2, 0] = 0.0  # only the sky's pixels left empty: no holes at all
    got = hole_fractions({"holes": holes}, {"reflected_hit": hit}, mirror, {})
    assert got["hole_fraction"] == 0.0
    # techniques without holes (rerender, virtual) report none
    assert hole_fractions({}, {"reflected_hit": hit}, mirror, {})["hole_fraction"] == 0.0


def test_resume_reruns_a_job_whose_scene_was_edited(tmp_path):
    scene = tmp_path / "scene.toml"
    original = (ROOT / "scenes" / "teapot-box.toml").read_text()
    scene.write_text(original)
    path = tmp_path / "e.toml"
    path.write_text(f"""
[bench]
name = "e"
frames = "0"
warmup = 0
repeats = 1
out = "out-e"

[[runs]]
scenes = ["{scene}"]
techniques = ["envmap"]
set = ["camera.width=24", "camera.height=18"]
""")
    first = run_bench(str(path), resume=True)
    assert first.ran == 1
    assert run_bench(str(path), resume=True).skipped == 1  # unchanged: kept
    scene.write_text(original.replace("color = [0.8, 0.1, 0.1]", "color = [0.1, 0.8, 0.1]"))
    edited = run_bench(str(path), resume=True)
    assert edited.ran == 1 and edited.skipped == 0
    assert edited.rows[0]["run"] != first.rows[0]["run"]
    # changed timing settings re-run the job as well
    path.write_text(path.read_text().replace("repeats = 1", "repeats = 2"))
    assert run_bench(str(path), resume=True).ran == 1


def test_a_still_scene_is_timed_on_warmup_plus_three_renders(tmp_path):
    path = tmp_path / "still.toml"
    text = f"""
[bench]
name = "still"
frames = "0"
warmup = 1
out = "out-still"
plots = false

[[runs]]
scenes = ["{ROOT / 'scenes' / 'four-spheres.toml'}"]
techniques = ["envmap"]
set = ["camera.width=24", "camera.height=24"]
"""
    path.write_text(text)
    row = run_bench(str(path)).rows[0]
    assert row["frames"] == 1 and row["repeats"] == 4
    assert row["warmup_renders"] == 1 and row["timed_frames"] == 3
    assert row["timing_warning"] == ""
    # a bench file that asks for fewer renders gets them, and the warning
    path.write_text(text.replace("warmup = 1", "warmup = 1\nrepeats = 1"))
    row = run_bench(str(path)).rows[0]
    assert row["repeats"] == 1 and "timed" in row["timing_warning"]
    # ... which the command line says too, not only report.md
    result = CliRunner().invoke(cli, ["bench", str(path)])
    assert result.exit_code == 0, result.output
    assert "warning: 1 run(s) timed on too few renders" in result.stderr
    report = (tmp_path / "out-still" / "report.md").read_text()
    assert "**warning:" in report and "*" in report.split("**warning:")[1].split("\n")[0]


def test_a_reference_is_rendered_again_when_the_renders_asked_for_change(tmp_path):
    """A reference timed on too few renders is not reused once the bench file asks for
    more: its renders are in its id, as a run's are in the run's."""
    from reflectcli.bench.runner import load_bench

    text = f"""
[bench]
name = "ids"
frames = "0"
warmup = 1
repeats = REPEATS

[[runs]]
scenes = ["{ROOT / 'scenes' / 'four-spheres.toml'}"]
techniques = ["envmap"]
"""
    ids = []
    for repeats in (1, 4):
        path = tmp_path / f"r{repeats}.toml"
        path.write_text(text.replace("REPEATS", str(repeats)))
        (job,) = load_bench(str(path)).jobs
        ids.append(job["reference"]["id"])
    assert ids[0] != ids[1]


def test_modern_preset_measures_screen_space_alone_and_the_chain_apart():
    from reflectcli.bench.runner import load_bench

    plan = load_bench(str(ROOT / "configs" / "bench" / "modern.toml"))
    screen = [j for j in plan.jobs if j["technique"] in ("ssr", "ppr")]
    alone = [j for j in screen if "technique.fallback" not in j["sweep"]
             and "technique.thickness" not in j["sweep"]]
    chain = [j for j in screen if "technique.fallback" in j["sweep"]]
    assert alone and chain
    assert {j["parameters"]["fallback"] for j in alone} == {"none"}
    assert {j["parameters"]["fallback"] for j in chain} == {"envmap"}
    assert {j["technique"] for j in alone} == {"ssr", "ppr"}


def test_running_jobs_prints_no_technique_notices(tmp_path, caplog):
    path = tmp_path / "n.toml"
    path.write_text(f"""
[bench]
name = "n"
frames = "0"
repeats = 1
out = "out-n"
plots = false

[[runs]]
scenes = ["{ROOT / 'scenes' / 'teapot-box.toml'}"]
techniques = ["envmap"]
set = ["camera.width=24", "camera.height=18"]
""")
    caplog.set_level("WARNING", logger="reflect")
    run_bench(str(path))
    assert not [r for r in caplog.records if "do not apply" in r.getMessage()]


def test_local_processes_sleep_when_idle(tmp_path, monkeypatch):
    """`--workers` processes share the cores: their OpenMP threads spin none (openmp.py),
    unless the user set how they wait."""
    import concurrent.futures

    from reflectcli import openmp

    seen = []

    class Recording(concurrent.futures.ProcessPoolExecutor):
        def __init__(self, *args, initializer=None, **kwargs):
            seen.append(initializer)
            super().__init__(*args, initializer=initializer, **kwargs)

    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", Recording)
    for defaulted, expected in ((True, openmp.no_spin), (False, None)):
        monkeypatch.setattr(openmp, "defaulted", defaulted)
        run_bench(str(_bench_file(tmp_path, f"w{int(defaulted)}")), workers=2)
        assert seen.pop() is expected


def test_a_scene_with_its_own_log_name_is_benched(tmp_path):
    """The bench reads each run's and reference's log where the scene's output.log puts it
    (it read timings.jsonl whatever the scene said, and failed)."""
    scene = tmp_path / "s.toml"
    text = (ROOT / "scenes" / "teapot-box.toml").read_text()
    assert "log =" not in text
    scene.write_text(text.replace("[output]\n", '[output]\nlog = "frames.jsonl"\n'))
    bench = tmp_path / "b.toml"
    bench.write_text(f"""
[bench]
name = "b"
frames = "0:1"
out = "out-b"

[[runs]]
scenes = ["{scene}"]
techniques = ["rerender"]
set = ["camera.width=32", "camera.height=24"]
""")
    result = CliRunner().invoke(cli, ["bench", str(bench)])
    assert result.exit_code == 0, result.output
    rows = read_jsonl(str(tmp_path / "out-b" / "results.jsonl"))
    assert len(rows) == 1 and rows[0]["frame_ms_median"] > 0
    assert rows[0]["reference_ms_median"] > 0


def test_a_stopped_bench_leaves_no_earlier_report_beside_its_rows(tmp_path):
    """Stopped after its first run, a bench's report.md and results.csv are of that run,
    marked incomplete: never the previous bench's (its other settings, its numbers) beside
    the new results.jsonl; the previous bench's plots are gone too."""
    path = _bench_file(tmp_path)
    run_bench(str(path))
    out = tmp_path / "out-t"
    assert (out / "contact-teapot-box.png").exists()

    def stop(row):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_bench(str(path), on_row=stop)
    rows = read_jsonl(str(out / "results.jsonl"))
    assert len(rows) == 1
    report = (out / "report.md").read_text()
    assert "**Incomplete: 1 of 4 runs finished**" in report
    assert report.count("| rerender |") == 1 and "| dprm |" not in report
    with open(out / "results.csv") as f:
        assert len(list(csv.reader(f))) == 2
    assert not list(out.glob("*.png"))
    resumed = run_bench(str(path), resume=True)
    assert resumed.ran == 3 and "Incomplete" not in (out / "report.md").read_text()
    assert (out / "contact-teapot-box.png").exists()


def test_plots_of_runs_no_longer_in_the_bench_are_removed(tmp_path):
    path = _bench_file(tmp_path)
    run_bench(str(path))
    out = tmp_path / "out-t"
    assert (out / "error-vs-maps.resolution.png").exists()
    stale = out / "contact-old-scene.png"
    stale.write_bytes(b"an earlier bench's plot")
    mine = out / "notes.png"
    mine.write_bytes(b"not a name the bench writes")
    text = path.read_text()
    path.write_text(text[:text.index("[[runs]]", text.index("[[runs]]") + 1)])  # no dprm
    run_bench(str(path), resume=True)
    assert not stale.exists() and not (out / "error-vs-maps.resolution.png").exists()
    assert mine.exists() and (out / "contact-teapot-box.png").exists()


def test_a_reference_timed_at_another_thread_count_is_timed_again(tmp_path):
    """The reference's images are reused, its times are the `x raytrace` ratio's other
    side: a bench at 1 thread after one at 2 renders the reference again rather than
    setting 1-thread times against 2-thread ones."""
    import numba

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs 2 cores")
    path = tmp_path / "th.toml"
    path.write_text(f"""
[bench]
name = "th"
frames = "0"
out = "out-th"
plots = false

[[runs]]
scenes = ["{ROOT / 'scenes' / 'teapot-box.toml'}"]
techniques = ["rerender"]
set = ["camera.width=32", "camera.height=24"]
""")
    for threads in (2, 1):
        (row,) = run_bench(str(path), threads=threads).rows
        assert row["threads"] == threads
        assert row["reference_timing_warning"] == ""
    (ref_log,) = (tmp_path / "out-th" / "references").rglob("timings.jsonl")
    assert read_jsonl(str(ref_log))[-1]["threads"] == 1


def test_a_reference_rendered_by_other_code_is_rendered_again(tmp_path, monkeypatch):
    """The version number is not raised per change: a reference's frames and times are
    reused only under the same digest of reflect's files (provenance.source_digest), or
    `x raytrace` and the PSNR columns would set this run against an older ray tracer."""
    from reflectcli import provenance

    path = tmp_path / "src.toml"
    path.write_text(f"""
[bench]
name = "src"
frames = "0"
out = "out-src"
plots = false

[[runs]]
scenes = ["{ROOT / 'scenes' / 'teapot-box.toml'}"]
techniques = ["rerender"]
set = ["camera.width=32", "camera.height=24"]
""")

    def reference_renders() -> int:
        (log,) = (tmp_path / "out-src" / "references").rglob("timings.jsonl")
        return len(read_jsonl(str(log)))

    run_bench(str(path))
    first = reference_renders()
    run_bench(str(path))
    assert reference_renders() == first  # the same code: reused
    monkeypatch.setattr(provenance, "source_digest", lambda: "another")
    run_bench(str(path))
    assert reference_renders() > first  # other code: rendered again
    (row,) = read_jsonl(str(tmp_path / "out-src" / "results.jsonl"))[-1:]
    assert row["versions"]["source"] == provenance.versions()["source"]


def test_contact_sheet_titles_say_whose_figures_they_are(tmp_path, monkeypatch):
    """The error map is one frame's; the mirror figure beside it is the run's HDR-FLIP over
    every frame. The title read 'LDR-FLIP 0.020, mirror 0.156' as if both were this frame's
    LDR-FLIP."""
    pytest.importorskip("matplotlib")
    from matplotlib.axes import Axes

    from reflectcli.bench import plots

    path = tmp_path / "c.toml"
    path.write_text(f"""
[bench]
name = "c"
frames = "1:3"
out = "out-c"
plots = false

[[runs]]
scenes = ["{ROOT / 'scenes' / 'teapot-box.toml'}"]
techniques = ["envmap"]
set = ["camera.width=32", "camera.height=24"]
""")
    rows = run_bench(str(path)).rows
    titles = []
    original = Axes.set_title
    monkeypatch.setattr(Axes, "set_title", lambda self, text, *a, **k: (
        titles.append(text), original(self, text, *a, **k))[1])
    plots._contact_sheet(rows, str(tmp_path / "sheet.png"))
    assert "raytrace (reference), frame 1" in titles
    (error,) = [t for t in titles if "mirror" in t]
    assert error.startswith("frame 1 ")
    assert "run HDR-FLIP mirror" in error or "run PSNR mirror" in error
