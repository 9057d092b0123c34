"""Bench files: size limits checked before the matrix is expanded, no empty sweep, and every
problem named by the bench file and its field, in one line (validate and bench alike)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from reflectcli.bench.config import MAX_RUNS, MAX_WARMUP, MAX_WORKERS
from reflectcli.cli import cli

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "teapot-box.toml"


@pytest.fixture(autouse=True)
def here(tmp_path, monkeypatch) -> Path:
    monkeypatch.chdir(tmp_path)  # messages name the bench file relative to the working folder
    return tmp_path


def bench_file(tmp_path: Path, bench: str = "", runs: str = "", sweep: str = "",
               techniques: str = '["raytrace"]') -> Path:
    path = tmp_path / "b.toml"
    path.write_text(f'[bench]\nname = "b"\nframes = "0"\nplots = false\n{bench}\n'
                    f'[[runs]]\nscenes = ["{SCENE}"]\ntechniques = {techniques}\n{runs}\n'
                    + (f"[runs.sweep]\n{sweep}\n" if sweep else ""))
    return path


def invoke(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def one_line(result) -> str:
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 2, (result.exit_code, result.output, result.exception)
    assert len(lines) == 1 and "Traceback" not in result.output, result.output
    return lines[0]


def refused(tmp_path: Path, path: Path, *args) -> str:
    """validate and bench give the same one line; bench writes nothing."""
    line = one_line(invoke("validate", path))
    assert one_line(invoke("bench", path, "--out", tmp_path / "o", *args)) == line
    assert not (tmp_path / "o").exists()
    return line


def test_too_many_runs_are_refused_before_the_matrix_is_expanded(tmp_path):
    values = "[" + ", ".join(str(16 + i) for i in range(30)) + "]"
    sweep = "\n".join(f'"{k}" = {values}' for k in ("camera.width", "camera.height",
                                                    "camera.fov_y"))
    path = bench_file(tmp_path, techniques='["raytrace", "raster"]',
                      sweep=sweep)
    start = time.perf_counter()
    line = refused(tmp_path, path)
    assert time.perf_counter() - start < 20  # not one scene opened per job (432,000 did 60 s)
    assert line.startswith("b.toml: runs: 54,000 runs") and f"{MAX_RUNS:,}" in line, line


def test_a_matrix_at_the_limit_is_counted_not_refused(tmp_path):
    from reflectcli.bench.config import BenchConfig, run_count

    cfg = BenchConfig.model_validate({
        "bench": {"name": "b"},
        "runs": [{"scenes": ["a", "b"], "techniques": ["raytrace"],
                  "sweep": {"x": list(range(MAX_RUNS // 4)), "y": [1, 2]}},
                 {"scenes": ["a"], "techniques": ["raster"]}]})
    assert run_count(cfg) == MAX_RUNS + 1


@pytest.mark.parametrize(("bench", "field"), [
    (f"warmup = {MAX_WARMUP + 1}", "bench.warmup"),
    ("warmup = 1000000", "bench.warmup"),
    ("repeats = 101", "bench.repeats"),
    ("threshold = nan", "bench.threshold"),
    ("threshold = inf", "bench.threshold"),
    ('out = ""', "bench.out"),
])
def test_bench_settings_have_limits(tmp_path, bench, field):
    line = refused(tmp_path, bench_file(tmp_path, bench=bench))
    assert line.startswith(f"b.toml: {field}:"), line


@pytest.mark.parametrize("workers", ["0", "-3", str(MAX_WORKERS + 1)])
def test_workers_out_of_range(tmp_path, workers):
    line = one_line(invoke("bench", bench_file(tmp_path), "--workers", workers,
                           "--out", tmp_path / "o"))
    assert line == f"--workers: must be 1..{MAX_WORKERS}", line
    assert not (tmp_path / "o").exists()


def test_empty_out_is_refused(tmp_path):
    line = one_line(invoke("bench", bench_file(tmp_path), "--out", ""))
    assert "--out" in line and "empty" in line, line


def test_an_empty_sweep_list_is_an_error_and_hides_no_other(tmp_path):
    path = bench_file(tmp_path, techniques='["nope", "raytrace"]',
                      sweep='"camera.width" = []\n"camera.widht" = [8]')
    result = invoke("validate", path)
    assert result.exit_code == 2 and "Traceback" not in result.output, result.output
    lines = result.stdout.splitlines()
    assert lines[0].startswith("b.toml: runs.0.sweep.camera.width: empty list"), lines
    assert any("unknown name 'nope'" in line for line in lines), lines
    assert any("camera.widht: unknown key" in line for line in lines), lines
    bench = invoke("bench", path, "--out", tmp_path / "o")
    assert bench.exit_code == 2 and bench.stderr.splitlines() == lines
    assert not (tmp_path / "o").exists()


def test_an_empty_sweep_list_alone(tmp_path):
    line = refused(tmp_path, bench_file(tmp_path, sweep='"camera.width" = []'))
    assert line.startswith("b.toml: runs.0.sweep.camera.width: empty list"), line


@pytest.mark.parametrize(("bench", "runs", "field"), [
    ('frames = "50:60"', "", "bench.frames"),
    ("", 'frames = "50:60"', "runs.0.frames"),
    ('frames = "x"', "", "bench.frames"),
])
def test_frames_name_the_bench_file_and_field(tmp_path, bench, runs, field):
    text = bench_file(tmp_path, runs=runs).read_text().replace('frames = "0"', bench)
    path = tmp_path / "b.toml"
    path.write_text(text)
    line = refused(tmp_path, path)
    assert line.startswith(f"b.toml: {field}: "), line
    assert "--frames" not in line


@pytest.mark.parametrize(("edit", "expected"), [
    # these read "runs (raytrace on ...): --set: camera.width: ..." and "--technique:
    # technique.name: ...", naming options the user never gave and no field of the file
    ({"sweep": '"camera.width" = [16, 0]'}, "b.toml: runs.0.sweep.camera.width: must be > 0 "
     "(raytrace on "),
    ({"sweep": '"camera.widht" = [16]'}, "b.toml: runs.0.sweep.camera.widht: unknown key "
     "(did you mean width?) (raytrace on "),
    ({"sweep": '"technique" = [{name = "raytrace", max_depth = -1}]'}, "b.toml: "
     "runs.0.sweep.technique: technique.max_depth: must be >= 0 (raytrace on "),
    ({"runs": 'set = ["camera.height=8", "camera.width=-1"]'}, "b.toml: runs.0.set: "
     "camera.width: must be > 0 (raytrace on "),
    ({"techniques": '["raytrce"]'}, "b.toml: runs.0.techniques: unknown name 'raytrce' "
     "(did you mean raytrace?)"),
])
def test_a_runs_problem_names_the_field_of_the_bench_file(tmp_path, edit, expected):
    line = refused(tmp_path, bench_file(tmp_path, **edit))
    assert line.startswith(expected), line
    assert "--set" not in line and "--technique" not in line


def test_a_problem_of_bench_set_is_still_blamed_on_set(tmp_path):
    # (it comes last, so it is what the sweep's value of the same field gave way to)
    line = one_line(invoke("bench", bench_file(tmp_path, sweep='"camera.width" = [16]'),
                           "--out", tmp_path / "o", "--set", "camera.width=0"))
    assert "--set: camera.width: must be > 0" in line, line
    assert not (tmp_path / "o").exists()


def test_reference_depth_names_the_bench_file_and_field(tmp_path):
    line = refused(tmp_path, bench_file(tmp_path, bench="reference_depth = 100000"))
    assert line.startswith("b.toml: bench.reference_depth: must be <= "), line
