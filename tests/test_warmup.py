"""The compile notice: one line on stderr once compiling the kernels has taken 3 s, even
though the warm-up (and the bench) quieten reflect's other notices meanwhile; none in the
test suite's own subprocesses (conftest.py turns it off there)."""

from __future__ import annotations

import io
import logging
import time

import pytest

from reflectcli import api, warmup


class SlowToCompile:
    """A technique whose first render takes as long as a compile."""

    class Params:
        @staticmethod
        def model_validate_json(text):
            return text

    def __init__(self, params, threads):
        pass

    def prepare(self, scene):
        logging.getLogger("reflect").warning("a warm-up scene notice: nobody's business")

    def render(self, state, frame, camera):
        time.sleep(0.5)


@pytest.fixture
def stderr(monkeypatch):
    """reflect's logger as `main()` sets it up, writing into a buffer."""
    monkeypatch.delenv(warmup.NO_NOTICE, raising=False)
    monkeypatch.setattr(warmup, "COMPILE_NOTICE_SECONDS", 0.05)
    buffer = io.StringIO()
    handler = logging.StreamHandler(buffer)
    handler.setFormatter(logging.Formatter("%(message)s"))
    logger = logging.getLogger("reflect")
    level = logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    yield buffer
    logger.removeHandler(handler)
    logger.setLevel(level)


def warm_up(monkeypatch, name: str) -> None:
    monkeypatch.setattr(api, "_warmed", {})
    monkeypatch.setattr(api, "technique_class", lambda _: SlowToCompile)
    monkeypatch.setattr(warmup, "warm_params", lambda params: params)
    api.warm_up(name, f'{{"name": "{name}"}}', 1)


def test_a_long_compile_prints_one_line(monkeypatch, stderr):
    warm_up(monkeypatch, "virtual")
    lines = stderr.getvalue().splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith("compiling the numba kernels of 'virtual'"), lines
    assert "20 s" not in lines[0] and "later runs load them" in lines[0]


def test_a_quick_warm_up_prints_nothing(monkeypatch, stderr):
    monkeypatch.setattr(warmup, "COMPILE_NOTICE_SECONDS", 5.0)
    warm_up(monkeypatch, "raster")
    time.sleep(0.1)
    assert stderr.getvalue() == ""


def test_the_notice_shows_inside_a_bench_job(monkeypatch, stderr):
    from reflectcli.bench.runner import technique_notices_quiet

    with technique_notices_quiet():
        warm_up(monkeypatch, "dprm")
    assert stderr.getvalue().startswith("compiling the numba kernels of 'dprm'")


def test_the_suite_turns_it_off(monkeypatch, stderr):
    monkeypatch.setenv(warmup.NO_NOTICE, "1")
    warm_up(monkeypatch, "envmap")
    assert stderr.getvalue() == ""
