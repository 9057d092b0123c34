"""Shared pydantic base and small field types for every config model."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field
from pydantic import Strict as StrictMode


def array_of(*items: Any) -> Any:
    """A fixed-length tuple field that takes a TOML array (a list): only the container is
    lax under the models' strict mode, its items stay strict."""
    return Annotated[tuple[items], StrictMode(False)]


Vec3 = array_of(float, float, float)
Vec2 = array_of(float, float)
Color = Annotated[Vec3, Field(description="linear RGB")]
PositiveInt = Annotated[int, Field(gt=0)]
UnitFloat = Annotated[float, Field(ge=0.0, le=1.0)]
# map techniques: capture at frame 0 only, every frame, or every N frames (maps/update.py)
UpdatePolicy = Literal["once", "every"] | Annotated[int, Field(ge=1)]


class Strict(BaseModel):
    """Unknown keys are errors (pbrt-style): a typo must not silently fall back to a default.
    NaN and infinity are errors too: every range check would let them through. Types are
    strict: `width = true`, `"160"` or `160.0` for an integer, or a string for a number, is
    an error, not converted (pydantic's lax mode rendered `width = true` 1 pixel wide); an
    integer still serves for a float."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, defer_build=True,
                              strict=True)


# ---------------------------------------------------------------- parameter tables
# A technique package's docstring opens with a Markdown table of its parameters:
#     | parameter | type | default | meaning |
# That table is the one source of each parameter's description: `described` copies the
# `meaning` cells into the Params fields, and `range_text` gives the allowed range that the
# `type` cell must show (a test holds the table and the model to each other).


def table_rows(doc: str) -> dict[str, tuple[str, str, str]]:
    """`{parameter: (type, default, meaning)}` from the docstring's parameter table; a row
    naming several parameters (`a`, `b`) gives each of them the same cells."""
    rows: dict[str, tuple[str, str, str]] = {}
    lines = [line.strip() for line in (doc or "").splitlines() if line.strip().startswith("|")]
    for line in lines[2:]:  # the header and its |---| rule
        cells = [c.strip() for c in line.strip("|").split("|")]
        if len(cells) < 4:
            continue
        names = [n.strip().strip("`") for n in cells[0].split(",")]
        for name in names:
            if name and not name.startswith("("):
                rows[name] = (cells[1], cells[2], cells[3])
    return rows


def range_text(field) -> str:
    """The allowed range of a numeric field from its constraints: `>= 0`, `[1, 16]`,
    `(0, 90)`, ...; "" when it has none."""
    lo = hi = None
    for m in field.metadata:
        for attr, side, closed in (("ge", "lo", True), ("gt", "lo", False),
                                   ("le", "hi", True), ("lt", "hi", False)):
            value = getattr(m, attr, None)
            if value is not None:
                if side == "lo":
                    lo = (value, closed)
                else:
                    hi = (value, closed)
    if lo is not None and hi is not None:
        return f"{'[' if lo[1] else '('}{lo[0]}, {hi[0]}{']' if hi[1] else ')'}"
    if lo is not None:
        return f"{'>=' if lo[1] else '>'} {lo[0]}"
    if hi is not None:
        return f"{'<=' if hi[1] else '<'} {hi[0]}"
    return ""


def model_fields_flat(model: type[BaseModel], prefix: str = "") -> dict:
    """Dotted name -> FieldInfo, nested models flattened (`maps.count`); `name` left out."""
    out = {}
    for name, field in model.model_fields.items():
        if name == "name" and not prefix:
            continue
        annotation = field.annotation
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            out.update(model_fields_flat(annotation, f"{prefix}{name}."))
        else:
            out[f"{prefix}{name}"] = field
    return out


def described(model: type[BaseModel], doc: str) -> type[BaseModel]:
    """Give `model`'s fields (nested ones included) the descriptions of the docstring table,
    so the table is written once. Returns the model."""
    rows = table_rows(doc)
    for name, field in model_fields_flat(model).items():
        if name in rows:
            field.description = rows[name][2]
    return model
