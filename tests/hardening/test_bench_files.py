"""Bench files a newcomer may write: a name that is no folder name, sweep values that are
tables or strings with escapes (written back for `--set` as TOML, not as Python's repr)."""

from __future__ import annotations

import datetime

import pytest
import tomli

from reflectcli.bench.config import _toml

from .common import TINY, assert_one_line, chdir, files_under, invoke, write

BENCH = ('[bench]\nname = "{name}"\nframes = "0"\nplots = false\n'
         '[[runs]]\nscenes = ["s.toml"]\ntechniques = ["raytrace"]\n')


@pytest.mark.parametrize("name", [".", ".."])
def test_a_bench_name_that_is_no_folder_name_is_refused(tmp_path, name):
    # out/bench/.. is out/ itself: the bench's results, references and runs landed there
    write(tmp_path, "s.toml", TINY)
    bench = write(tmp_path, "b.toml", BENCH.replace("{name}", name))
    with chdir(tmp_path):
        assert_one_line(invoke("validate", bench), "b.toml: bench.name: must name a folder")
        assert_one_line(invoke("bench", bench), "b.toml: bench.name: must name a folder")
    assert files_under(tmp_path / "out") == []


def test_a_table_swept_is_a_table(tmp_path):
    # Python's repr gave `{'frames': 2, ...}`, which --set read as no table at all
    write(tmp_path, "s.toml", TINY)
    bench = write(tmp_path, "b.toml", BENCH.replace("{name}", "b") + (
        '[runs.sweep]\n"camera.path" = [{ frames = 2, keys = [{ eye = [0, 1, 3], '
        'target = [0, 0.5, 0] }] }]\n'))
    with chdir(tmp_path):
        result = invoke("validate", bench)
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize("value", [
    'a\\b"c\nd\u00e9\x01', [1, "x", [2.5, True]], {"frames": 2, "a.b": [{"eye": [0, 1]}]},
    1e300, -0.0, float("inf"), 10**30, datetime.date(1979, 5, 27),
    datetime.datetime(1979, 5, 27, 7, 32), datetime.time(7, 32),
])
def test_sweep_values_are_written_back_as_toml(value):
    assert tomli.loads(f"x = {_toml(value)}")["x"] == value


def test_a_bench_folder_that_is_a_file_is_refused_by_validate_too(tmp_path):
    # validate said ok; bench failed with "[Errno 17] File exists: ..." and exit code 1
    write(tmp_path, "s.toml", TINY)
    write(tmp_path, "taken", "a file")
    bench = write(tmp_path, "b.toml", BENCH.replace("{name}", "b").replace(
        "plots = false\n", 'plots = false\nout = "taken"\n'))
    with chdir(tmp_path):
        for command in ("validate", "bench"):
            assert_one_line(invoke(command, bench),
                            "b.toml: bench.out: cannot write to", "Not a directory")
        assert_one_line(invoke("bench", bench, "--out", tmp_path / "s.toml" / "x"),
                        "--out: cannot write to", "Not a directory")
    assert (tmp_path / "taken").read_text() == "a file"
