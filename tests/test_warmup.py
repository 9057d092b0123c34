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


@pytest.mark.parametrize("name", ["envmap", "distmap", "dprm", "virtual"])
def test_the_warm_up_makes_its_maps_small(name):
    """The kernels compile for the maps' types, not their sizes: the warm-up scene's maps
    are a few texels whatever the scene asks (a distmap at 1024 texels and 8 layers held 6
    GiB of warm-up maps before), and its parameters stay valid."""
    cls = api.technique_class(name)
    asked = {"envmap": {"resolution": 4096}, "distmap": {"resolution": 4096, "layers": 8},
             "dprm": {"maps": {"resolution": 8192, "count": 4096, "per_frame": 64}},
             "virtual": {"explosion": {"resolution": 4096}}}[name]
    params = cls.Params.model_validate({"name": name, **asked})
    warm = cls.Params.model_validate_json(warmup.warm_params(params.model_dump_json()))
    holder = warm.maps if name == "dprm" else warm.explosion if name == "virtual" else warm
    assert holder.resolution == warmup.WARM_MAP_SIDE
    if name == "dprm":
        assert (warm.maps.count, warm.maps.per_frame) == (warmup.WARM_MAPS, warmup.WARM_MAPS)
    if name == "distmap":
        assert warm.layers == 8  # layers are a loop bound in the kernels: kept


def test_a_dprm_warm_up_keeps_a_grid_square_and_fewer_maps():
    cls = api.technique_class("dprm")
    for maps, expected in (({"count": 1, "per_frame": 1}, 1),
                           ({"count": 3, "layout": "fibonacci", "per_frame": 2}, 3),
                           ({"count": 7, "layout": "fibonacci", "per_frame": 5}, 4)):
        params = cls.Params.model_validate({"name": "dprm", "maps": maps})
        warm = cls.Params.model_validate_json(warmup.warm_params(params.model_dump_json()))
        assert warm.maps.count == expected and warm.maps.per_frame <= expected


def test_the_shipped_wave_is_the_scripts():
    """reflectcli/data/warm-up-wave.ply is what scripts/make_warm_wave.py makes."""
    import sys
    from pathlib import Path

    import trimesh

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
    try:
        import make_warm_wave
    finally:
        sys.path.pop(0)
    made = make_warm_wave.make_wave()
    shipped = trimesh.load(warmup.WAVE_PATH, process=False)
    assert (shipped.faces == made.faces).all()
    assert abs(shipped.vertices - made.vertices).max() < 1e-6
