"""Each technique module opens with a table of its parameters (Mitsuba style) that stays in
step with its pydantic model."""

from __future__ import annotations

import sys

import pytest

from reflectcli.techniques.base import parameter_table, toml_value
from reflectcli.techniques.registry import TECHNIQUES


@pytest.mark.parametrize("name", sorted(TECHNIQUES))
def test_docstring_table_lists_every_parameter(name):
    cls = TECHNIQUES[name]
    doc = sys.modules[cls.Params.__module__].__doc__  # the table lives with Params
    table = [line for line in doc.splitlines() if line.startswith("|")]
    assert table[0].startswith("| parameter | type | default |")
    for pname, _, default, _ in parameter_table(cls.Params):
        row = next((line for line in table if f"`{pname}`" in line), None)
        assert row is not None, f"{name}: {pname} missing from the docstring table"
        cells = [c.strip() for c in row.strip("|").split("|")]
        if default not in ("(unset)", "{}"):
            assert cells[2] == default.strip('"') or cells[2] == default, (pname, cells)


def test_toml_values():
    assert toml_value("cube") == '"cube"' and toml_value(True) == "true"
    assert toml_value((1.0, 2.0, 3.0)) == "[1.0, 2.0, 3.0]" and toml_value(None) == "(unset)"
