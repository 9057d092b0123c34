"""Environment variables the libraries read when they load: a value they cannot use is one
line naming the variable, exit code 2 (NUMBA_NUM_THREADS=0 and NUMBA_THREADING_LAYER=bogus
were numba's traceback at the first kernel; NUMBA_NUM_THREADS=abc a warning quoting one)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from reflectcli.environment import MAX_THREADS, environment_problems

from .common import TINY, write


@pytest.mark.parametrize(("name", "value", "said"), [
    ("NUMBA_NUM_THREADS", "0", f"must be a whole number 1..{MAX_THREADS}"),
    ("NUMBA_NUM_THREADS", "abc", "must be a whole number"),
    ("NUMBA_NUM_THREADS", "", "must be a whole number"),
    ("NUMBA_NUM_THREADS", " 2", "must be a whole number"),
    ("NUMBA_NUM_THREADS", str(MAX_THREADS + 1), "must be a whole number"),
    ("NUMBA_NUM_THREADS", "9" * 40, "must be a whole number"),
    ("NUMBA_THREADING_LAYER", "bogus", "must be one of default, safe"),
    ("OMP_WAIT_POLICY", "sometimes", "must be active or passive"),
])
def test_unusable_values_are_named(name, value, said):
    (problem,) = environment_problems({name: value})
    assert str(problem) == f"environment: {name}: {said}" + str(problem).split(said)[1]
    assert f"(is '{value}')" in str(problem)


@pytest.mark.parametrize("env", [
    {}, {"NUMBA_NUM_THREADS": "1"}, {"NUMBA_NUM_THREADS": str(MAX_THREADS)},
    {"NUMBA_THREADING_LAYER": "omp"}, {"NUMBA_THREADING_LAYER": "workqueue"},
    {"OMP_WAIT_POLICY": "PASSIVE"}, {"OMP_WAIT_POLICY": "active"},
])
def test_usable_values_pass(env):
    assert environment_problems(env) == []


def test_tbb_without_tbb_is_one_line(monkeypatch):
    from reflectcli import environment

    monkeypatch.setattr(environment, "_tbb_loads", lambda: False)
    (problem,) = environment_problems({"NUMBA_THREADING_LAYER": "tbb"})
    assert "needs Intel TBB, which is not installed" in str(problem)


def test_the_command_line_refuses_in_one_line(tmp_path):
    scene = write(tmp_path, "s.toml", TINY)
    env = {**os.environ, "NUMBA_NUM_THREADS": "0"}
    done = subprocess.run([sys.executable, "-m", "reflectcli.cli", "render", str(scene),
                           "--out", str(tmp_path / "o")], capture_output=True, text=True,
                          env=env, cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip() == ("environment: NUMBA_NUM_THREADS: must be a whole number "
                                   f"1..{MAX_THREADS} (is '0')")
    assert not (tmp_path / "o").exists()
