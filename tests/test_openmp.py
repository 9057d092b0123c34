"""How numba's OpenMP workers wait (reflectcli/openmp.py): set before libgomp reads it, an
explicit setting kept, and processes sharing the cores sleeping at once."""

from __future__ import annotations

import multiprocessing
import os
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor

import pytest

from reflectcli import openmp


def _fresh(env_extra: dict[str, str], code: str) -> str:
    """stdout of `code` in a new interpreter whose environment has no OpenMP setting but
    `env_extra`."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT", "REFLECT_OPENMP_DEFAULT")}
    env.update(env_extra)
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                          text=True, check=True, timeout=120).stdout.strip()


_SHOW = ("import os, reflectcli; print(os.environ.get('OMP_WAIT_POLICY'), "
         "os.environ.get('GOMP_SPINCOUNT'), reflectcli.openmp.defaulted)")


def test_default_is_passive_after_a_short_spin():
    assert _fresh({}, _SHOW) == f"passive {openmp.SPIN} True"


@pytest.mark.parametrize("env, shown", [
    ({"OMP_WAIT_POLICY": "ACTIVE"}, "ACTIVE None False"),
    ({"GOMP_SPINCOUNT": "7"}, "None 7 False"),
    # a parent's mark, inherited, with the user's own setting since: the user's
    ({"REFLECT_OPENMP_DEFAULT": f"passive/{openmp.SPIN}", "OMP_WAIT_POLICY": "active"},
     "active None False"),
    ({"REFLECT_OPENMP_DEFAULT": f"passive/{openmp.SPIN}", "OMP_WAIT_POLICY": "passive",
      "GOMP_SPINCOUNT": "1000000"}, "passive 1000000 False"),
    # the mark alone, its values unset since: the default made anew
    ({"REFLECT_OPENMP_DEFAULT": f"passive/{openmp.SPIN}"}, f"passive {openmp.SPIN} True"),
    # the parent's default as it left it: still the default
    ({"REFLECT_OPENMP_DEFAULT": f"passive/{openmp.SPIN}", "OMP_WAIT_POLICY": "passive",
      "GOMP_SPINCOUNT": openmp.SPIN}, f"passive {openmp.SPIN} True"),
    ({"REFLECT_OPENMP_DEFAULT": "passive/0", "OMP_WAIT_POLICY": "passive",
      "GOMP_SPINCOUNT": "0"}, "passive 0 True"),
])
def test_an_explicit_setting_is_kept(env, shown):
    assert _fresh(env, _SHOW) == shown


def test_set_before_libgomp_is_loaded():
    """Importing the package, its api and its command line loads no OpenMP runtime (libgomp
    reads the settings once, when numba first loads it for a parallel kernel)."""
    code = ("import reflectcli.api, reflectcli.cli, reflectcli.bench.runner; "
            "print('libgomp' in open('/proc/self/maps').read())")
    assert _fresh({}, code) == "False"


def _spin_count() -> str | None:
    return os.environ.get("GOMP_SPINCOUNT")


def test_spawned_workers_sharing_the_cores_do_not_spin(monkeypatch):
    """The initializer `reflect bench --workers` gives its processes (which inherit the
    default; tests/bench/test_bench.py checks that it is given) leaves them no spin."""
    monkeypatch.setenv("GOMP_SPINCOUNT", openmp.SPIN)
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"),
                             initializer=openmp.no_spin) as ex:
        assert ex.submit(_spin_count).result(timeout=120) == "0"
