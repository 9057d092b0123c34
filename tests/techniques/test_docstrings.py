"""Each technique module opens with a table of its parameters (Mitsuba style) that stays in
step with its pydantic model."""

from __future__ import annotations

import pytest

from reflectcli.config.base import model_fields_flat, range_text, table_rows
from reflectcli.techniques.params import parameter_table, toml_value
from reflectcli.techniques.registry import PARAMS, technique_doc


@pytest.mark.parametrize("name", sorted(PARAMS))
def test_docstring_table_lists_every_parameter(name):
    params = PARAMS[name]
    doc = technique_doc(name)
    table = [line for line in doc.splitlines() if line.startswith("|")]
    assert table[0].startswith("| parameter | type | default |")
    for pname, _, default, _, _ in parameter_table(params):
        row = next((line for line in table if f"`{pname}`" in line), None)
        assert row is not None, f"{name}: {pname} missing from the docstring table"
        cells = [c.strip() for c in row.strip("|").split("|")]
        if default not in ("(unset)", "{}"):
            assert cells[2] == default.strip('"') or cells[2] == default, (pname, cells)


def test_toml_values():
    assert toml_value("cube") == '"cube"' and toml_value(True) == "true"
    assert toml_value((1.0, 2.0, 3.0)) == "[1.0, 2.0, 3.0]" and toml_value(None) == "(unset)"


@pytest.mark.parametrize("name", sorted(PARAMS))
def test_table_rows_are_params_fields_with_their_ranges(name):
    """One row per Params field and one field per row; a row's type cell shows the field's
    allowed range; the field's description is the row's meaning (the table is the source)."""
    rows = table_rows(technique_doc(name))
    fields = model_fields_flat(PARAMS[name])
    assert set(rows) == set(fields), name
    for pname, field in fields.items():
        type_cell, _, meaning = rows[pname]
        allowed = range_text(field)
        assert allowed in type_cell, (name, pname, type_cell, allowed)
        assert field.description == meaning


def test_range_text():
    from pydantic import Field

    from reflectcli.config.base import Strict

    class M(Strict):
        a: int = Field(default=1, ge=0, le=4)
        b: float = Field(default=1.0, gt=0, lt=90)
        c: float = Field(default=1.0, gt=1.0)
        d: int = 1

    f = M.model_fields
    assert [range_text(f[k]) for k in "abcd"] == ["[0, 4]", "(0, 90)", "> 1.0", ""]


def test_techniques_cli_shows_table_descriptions_and_ranges():
    from click.testing import CliRunner

    from reflectcli.cli import cli

    out = CliRunner().invoke(cli, ["techniques"]).output
    line = next(x for x in out.splitlines() if x.strip().startswith("max_depth"))
    assert "in [0, 64]" in line and "(mirror bounces followed;" in line


def test_type_names_unwrap_annotated_and_say_optional_only_for_none():
    from typing import Annotated, Literal

    from pydantic import Field

    from reflectcli.config.base import UpdatePolicy
    from reflectcli.techniques.params import type_name

    assert type_name(UpdatePolicy) == '"once" | "every" | int >= 1'
    assert type_name(Annotated[int, Field(ge=1)]) == "int >= 1"
    assert type_name(Literal["a"] | int) == '"a" | int'  # a Union without None
    assert type_name(float | None) == "float (optional)"
