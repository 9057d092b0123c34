"""Parameter tables of Params models, for `reflect techniques` and the docstring tests.

Light: pydantic and config.base only, so listing techniques loads no kernels.
"""

from __future__ import annotations

from types import SimpleNamespace, UnionType
from typing import Annotated, Literal, Union, get_args, get_origin

from pydantic import BaseModel

from ..config.base import range_text


def parameter_table(params: type[BaseModel],
                    prefix: str = "") -> list[tuple[str, str, str, str, str]]:
    """(dotted name, type, default, allowed range, description) rows from a Params model,
    nested models flattened (`maps.count`), for `reflect techniques`: never a hand-kept list.
    Descriptions come from the package docstring's table (`config.base.described`)."""
    rows = []
    for name, field in params.model_fields.items():
        if name == "name" and not prefix:
            continue
        annotation = field.annotation
        default = field.get_default(call_default_factory=True)
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            rows += parameter_table(annotation, f"{prefix}{name}.")
            continue
        rows.append((f"{prefix}{name}", type_name(annotation), toml_value(default),
                     range_text(field), field.description or ""))
    return rows


def type_name(annotation) -> str:
    """A readable type: int, float, "a" | "b", xyz, ..."""
    origin = get_origin(annotation)
    args = get_args(annotation)
    if origin is Literal:
        return " | ".join(toml_value(a) for a in args)
    if origin is Annotated:  # Annotated[int, Field(ge=1)] -> "int >= 1"
        base, *extra = args
        # a Field(...) carries its constraints in .metadata; annotated_types.Ge & co. are bare
        metadata = [m for e in extra for m in getattr(e, "metadata", [e])]
        bounds = range_text(SimpleNamespace(metadata=metadata))
        return f"{type_name(base)} {bounds}" if bounds else type_name(base)
    if origin in (Union, UnionType):
        text = " | ".join(type_name(a) for a in args if a is not type(None))
        return text + " (optional)" if type(None) in args else text
    if origin is tuple and len(args) == 3 and all(a is float for a in args):
        return "xyz"
    if origin is dict:
        return f"table of {type_name(args[1])}"
    return getattr(annotation, "__name__", str(annotation))


def toml_value(value) -> str:
    """A default as it would be written in TOML."""
    if value is None:
        return "(unset)"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, tuple | list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + "}"
    return str(value)
