"""Messages a user can act on: "did you mean" for unknown keys and tags, plain words instead
of pydantic's type and class names, and list items named the way `--set` addressed them."""

from __future__ import annotations

import difflib
import inspect
import re
import types
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import BaseModel

from .names import NAME_PATTERN

_TAGS = ("shape", "kind", "name")


def did_you_mean(word: str, known) -> str:
    close = difflib.get_close_matches(str(word), [str(k) for k in known], n=1, cutoff=0.6)
    return f" (did you mean {close[0]}?)" if close else ""


def _candidates(tp) -> list:
    origin = get_origin(tp)
    if origin is Annotated:
        return _candidates(get_args(tp)[0])
    if origin in (Union, types.UnionType):
        out: list = []
        for arg in get_args(tp):
            out += _candidates(arg)
        return out
    return [tp]


def _is_model(tp) -> bool:
    return inspect.isclass(tp) and issubclass(tp, BaseModel)


def _pick(models: list, node) -> type[BaseModel] | None:
    if len(models) == 1:
        return models[0]
    if not isinstance(node, dict):
        return None
    for model in models:
        for tag in _TAGS:
            field = model.model_fields.get(tag)
            if field is None or get_origin(field.annotation) is not Literal:
                continue
            value = node.get(tag, field.default if tag == "kind" else None)
            if value in get_args(field.annotation):
                return model
    return None


def known_keys(root: type[BaseModel], loc: tuple, data: Any) -> list[str]:
    """The keys the model at `loc` (the table holding an unknown key) accepts, or []."""
    tp: Any = root
    node = data
    for part in loc:
        cands = _candidates(tp)
        model = _pick([c for c in cands if _is_model(c)], node)
        if model is not None:
            if part not in model.model_fields:
                return []
            tp = model.model_fields[part].annotation
        else:
            containers = [c for c in cands if get_origin(c) in (list, dict, tuple)]
            if not containers:
                return []
            args = get_args(containers[0])
            tp = args[-1] if get_origin(containers[0]) is dict else args[0]
        try:
            node = node[part]
        except (KeyError, IndexError, TypeError):
            node = None
    model = _pick([c for c in _candidates(tp) if _is_model(c)], node)
    return list(model.model_fields) if model is not None else []


_PLAIN = {
    "model_type": "must be a table",
    "model_attributes_type": "must be a table",
    "dict_type": "must be a table",
    "list_type": "must be an array",
    "tuple_type": "must be an array",
    "float_type": "must be a number",
    "float_parsing": "must be a number",
    "int_type": "must be an integer",
    "int_parsing": "must be an integer",
    "int_from_float": "must be an integer",
    "string_type": "must be a string",
    "bool_type": "must be true or false",
    "bool_parsing": "must be true or false",
    "finite_number": "must be a finite number",
}


def tag_name(ctx: dict | None) -> str:
    """The key a tagged union is told apart by. A callable discriminator (materials' `_kind`,
    defaulting to solid) is reported by pydantic as `_kind()`: the user wrote `kind`."""
    name = str((ctx or {}).get("discriminator", "")).strip("'")
    if name.endswith("()"):
        name = name[:-2].lstrip("_")
    return name


def plain_message(err: dict, root: type[BaseModel] | None, loc: tuple, data: Any) -> str | None:
    """A plain-words message for a pydantic error, or None to keep the default one."""
    kind = err["type"]
    ctx = err.get("ctx") or {}
    if kind == "extra_forbidden":
        known = known_keys(root, loc[:-1], data) if root is not None and loc else []
        return "unknown key" + (did_you_mean(loc[-1], known) if loc else "")
    if kind == "union_tag_invalid":
        tags = re.findall(r"'([^']*)'", str(ctx.get("expected_tags", "")))
        tag = ctx.get("tag", "")
        return (f"unknown {tag_name(ctx) or 'tag'} '{tag}'"
                f"{did_you_mean(tag, tags)} (known: {', '.join(tags)})")
    if kind == "union_tag_not_found":
        return f"needs '{tag_name(ctx) or 'name'}'"
    if kind in ("too_short", "too_long"):
        limit = ctx.get("min_length" if kind == "too_short" else "max_length")
        word = "at least" if kind == "too_short" else "at most"
        return f"needs {word} {limit} item(s)"
    if kind == "literal_error":
        return "must be " + str(ctx.get("expected", "")).replace("'", '"')
    if kind == "string_pattern_mismatch" and ctx.get("pattern") == NAME_PATTERN:
        return "must be ASCII letters, digits, '.', '_' or '-' (it names a folder)"
    if kind in _PLAIN:
        return _PLAIN[kind]
    msg = err.get("msg", "")
    if re.search(r"instance of [A-Z]\w+|[a-z][A-Za-z]*Params|[A-Z][a-z]+Config", msg):
        return re.sub(r"\b[A-Z][A-Za-z]+(Params|Config|Object|Mirror|Material|Light)\b",
                      "table", msg)
    return None


def by_name(problems: list, overrides, data: dict) -> list:
    """Problems about list items `--set` addressed by name or by an index from the end name
    them the same way, every item of the path (`mirrors.-1.corners.-1`, not
    `mirrors.-1.corners.3`)."""
    from ..errors import Problem

    aliases: dict[str, str] = {}  # a path as errors give it (indices from the start) -> as set
    for assignment in overrides:
        parts = assignment.split("=", 1)[0].strip().split(".")
        node: Any = data
        canonical: list[str] = []
        for i, part in enumerate(parts):
            if isinstance(node, list):
                if part.lstrip("-").isdigit():
                    idx = int(part)
                    if not -len(node) <= idx < len(node):
                        break
                else:
                    idx = next((k for k, it in enumerate(node)
                                if isinstance(it, dict) and it.get("name") == part), None)
                    if idx is None:
                        break
                canonical.append(str(idx % len(node)))
                if canonical[-1] != part:
                    aliases[".".join(canonical)] = ".".join(parts[: i + 1])
                node = node[idx]
            elif isinstance(node, dict):
                canonical.append(part)
                node = node.get(part)
            else:
                break
    if not aliases:
        return problems
    longest_first = sorted(aliases.items(), key=lambda a: -len(a[0]))
    out = []
    for p in problems:
        field = p.field
        for index_form, name_form in longest_first:
            if field == index_form or field.startswith(index_form + "."):
                field = name_form + field[len(index_form):]
                break
        out.append(Problem(p.file, field, p.message) if field != p.field else p)
    return out





def note_dropped_parameters(current, technique: str, root) -> None:
    """--technique replaces the scene's [technique]: say which of its parameters the new
    technique does not take over (each technique falls back to its own defaults)."""
    import logging

    if not isinstance(current, dict) or not current.get("name"):
        return
    dropped = sorted(k for k in current if k != "name")
    if not dropped:
        return
    fields = set(known_keys(root, ("technique",), {"technique": {"name": technique}}))
    shared = [k for k in dropped if k in fields]
    message = (f"--technique {technique}: the scene's {current['name']} parameters do not "
               f"apply ({', '.join(dropped)}); {technique} uses its own defaults")
    if shared:
        message += f" (set them with --set technique.{shared[0]}=...)"
    logging.getLogger("reflect").warning(message)
