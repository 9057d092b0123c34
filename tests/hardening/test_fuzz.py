"""Mutated bundled scenes (hypothesis, a bounded budget): no traceback, validate and render
agree, a refusal writes nothing and says each problem in one line. `make fuzz` runs the same
check on 10,000 configs with a hang detector (scripts/fuzz.py)."""

from __future__ import annotations

import logging

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from reflectcli.fuzz import base_scenes, check, one_case

BASES = base_scenes()


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(seed=st.integers(min_value=0, max_value=2**32 - 1))
def test_mutated_scenes_keep_every_promise(tmp_path_factory, seed):
    logger = logging.getLogger("reflect")
    level = logger.level
    logger.setLevel(logging.CRITICAL)  # recapture notices of mutated scenes: not the point
    folder = tmp_path_factory.mktemp("fuzz")
    _, text = one_case(seed, BASES)
    path = folder / "s.toml"
    path.write_text(text)
    try:
        result = check(str(path), str(folder / "out"), str(folder / "cache"))
    finally:
        logger.setLevel(level)
    assert result["failure"] is None, (seed, result.get("detail"), text)
