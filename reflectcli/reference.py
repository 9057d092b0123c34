"""The scene file documented from its pydantic models: `reflect schema` prints the JSON
schema (for editors), and `scene_reference()` renders every key with its type, default,
range and description as Markdown (docs/scene-reference.md, checked by a test)."""

from __future__ import annotations

import json
from typing import Any


def scene_schema() -> dict:
    """The scene file's JSON schema, the technique table the union of every registered
    technique's parameters (so it lives above config/, beside the registry)."""
    from .techniques.registry import scene_model

    schema = scene_model().model_json_schema()
    schema["title"] = "reflect scene file"
    return schema


def _type(prop: dict, defs: dict) -> str:
    if "$ref" in prop:
        return defs[prop["$ref"].split("/")[-1]].get("title", "table")
    if "const" in prop:
        return json.dumps(prop["const"])
    if "enum" in prop:
        return " \\| ".join(json.dumps(v) for v in prop["enum"])
    for key in ("anyOf", "oneOf"):
        if key in prop:
            return " or ".join(_type(p, defs) for p in prop[key])
    kind = prop.get("type", "any")
    if kind == "array":
        if "prefixItems" in prop:
            return "[" + ", ".join(_type(p, defs) for p in prop["prefixItems"]) + "]"
        return f"array of {_type(prop.get('items', {}), defs)}"
    if kind == "object" and "additionalProperties" in prop:
        return f"table of {_type(prop['additionalProperties'], defs)}"
    return {"number": "float", "integer": "int", "string": "string", "boolean": "bool",
            "null": "none"}.get(kind, kind)


def _range(prop: dict) -> str:
    parts = []
    for key, sign in (("exclusiveMinimum", ">"), ("minimum", ">="), ("exclusiveMaximum", "<"),
                      ("maximum", "<="), ("minItems", "items >="), ("maxItems", "items <="),
                      ("pattern", "matches")):
        if key in prop:
            parts.append(f"{sign} {prop[key]}")
    for key in ("anyOf",):
        for p in prop.get(key, []):
            r = _range(p)
            if r:
                parts.append(r)
    return ", ".join(parts)


def _rows(name: str, model: dict, defs: dict) -> list[str]:
    required = set(model.get("required", []))
    lines = [f"### {name}", ""]
    if model.get("description"):
        lines += [" ".join(model["description"].split()), ""]
    lines += ["| key | type | default | range | description |", "|---|---|---|---|---|"]
    for key, prop in model.get("properties", {}).items():
        default: Any = "required" if key in required else json.dumps(prop.get("default"))
        lines.append(f"| `{key}` | {_type(prop, defs)} | {default} | {_range(prop)} | "
                     f"{' '.join(str(prop.get('description', '')).split())} |")
    return [*lines, ""]


def scene_reference() -> str:
    schema = scene_schema()
    defs = schema.get("$defs", {})
    out = ["# Scene file reference", "",
           "Generated from the pydantic models (`reflect schema` prints the JSON schema; "
           "`scripts/scene_reference.py` rewrites this file). Every table rejects unknown "
           "keys; numbers must be finite. Size limits (image, frames, tessellation, "
           "triangles, files) are listed in `reflectcli/config/limits.py`.", ""]
    from .config import limits

    table = [line for line in (limits.__doc__ or "").splitlines() if line.startswith("|")]
    out += ["### size limits", "", *table, ""]
    out += _rows("top level", schema, defs)
    for name in sorted(defs):
        out += _rows(defs[name].get("title", name) + f" (`{name}`)", defs[name], defs)
    return "\n".join(out)
