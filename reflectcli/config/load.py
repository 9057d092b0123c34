"""TOML -> SceneConfig: includes, section files, --set overrides, and errors naming the file.

A scene may `include = ["../configs/x.toml", ...]`: those files are merged first (in order),
then the including file on top. A section may be a string naming a TOML file instead of a
table (`camera = "cameras/walk.toml"`); that file holds the section either under its own
name (`[camera]`, `[[mirrors]]`) or at its top level. Paths are relative to the file that
writes them. Every value remembers the file it came from, so an error names that file.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from typing import Any

import tomli
from pydantic import BaseModel, ValidationError

from ..errors import Problem, Problems
from .files import file_problem, read_toml_file
from .limits import MAX_INCLUDE_DEPTH, MAX_TOML_BYTES, limit_problems, origin
from .memory import memory_problem
from .suggest import by_name, note_dropped_parameters, plain_message, tag_name

SECTION_FILES = ("camera", "mirrors", "technique", "materials", "lights", "objects", "output")

Provenance = dict[tuple, str]


def read_toml(path: str, field: str = "", referrer: str | None = None) -> dict:
    return read_toml_file(path, field, referrer)


def _mark(data: Any, source: str, prefix: tuple, prov: Provenance) -> None:
    prov[prefix] = source
    if isinstance(data, dict):
        for k, v in data.items():
            _mark(v, source, (*prefix, k), prov)
    elif isinstance(data, list):
        for i, v in enumerate(data):
            _mark(v, source, (*prefix, i), prov)


def _merge(base: dict, top: dict) -> dict:
    """Deep merge: tables merge key by key, anything else in `top` replaces `base`."""
    out = dict(base)
    for k, v in top.items():
        out[k] = _merge(out[k], v) if isinstance(out.get(k), dict) and isinstance(v, dict) else v
    return out


def load_raw(path: str, prov: Provenance, stack: tuple = ()) -> dict:
    """Read a config file with its includes and section files resolved."""
    path = os.path.normpath(os.path.abspath(path))
    display = os.path.relpath(path) if not os.path.relpath(path).startswith("..") else path
    if path in stack:
        raise Problems([Problem(display, "include", "include cycle")])
    if len(stack) >= MAX_INCLUDE_DEPTH:
        raise Problems([Problem(display, "include", f"includes nested more than "
                                                    f"{MAX_INCLUDE_DEPTH} files deep")])
    data = read_toml(path)
    here = os.path.dirname(path)
    merged: dict = {}
    local: Provenance = {}
    includes = data.pop("include", [])
    if isinstance(includes, str):
        includes = [includes]
    if not isinstance(includes, list) or not all(isinstance(i, str) for i in includes):
        raise Problems([Problem(display, "include", "must be a list of file paths")])
    for inc in includes:
        sub: Provenance = {}
        inc_path = os.path.join(here, inc)
        reason = file_problem(inc_path, MAX_TOML_BYTES, "TOML file")
        if reason is not None:
            shown = f": {inc}" if "\0" not in inc else ""
            raise Problems([Problem(display, "include", reason + shown)])
        included = load_raw(inc_path, sub, (*stack, path))
        _rebase(included, os.path.dirname(os.path.abspath(inc_path)), here)
        merged = _merge(merged, included)
        local.update(sub)
    from_files = set()
    for key in SECTION_FILES:
        if isinstance(data.get(key), str):
            from_files.add(key)
            ref = os.path.join(here, data[key])
            section = read_toml(ref, key, display)
            data[key] = section.get(key, section) if isinstance(section, dict) else section
            ref_display = os.path.relpath(os.path.normpath(ref))
            _mark(data[key], ref_display, (key,), local)
            _rebase({key: data[key]}, os.path.dirname(os.path.abspath(ref)), here)
    for k, v in data.items():
        if k not in from_files:
            _mark(v, display, (k,), local)
    merged = _merge(merged, data)
    prov.update(local)
    return merged


def _rebase(data: dict, from_dir: str, to_dir: str) -> None:
    """File paths in objects, mirrors and materials are relative to the file that wrote them;
    rewrite those read from another directory relative to the including file."""
    if os.path.samefile(from_dir, to_dir):
        return
    items = []
    for key in ("objects", "mirrors"):
        if isinstance(data.get(key), list):
            items += data[key]
    if isinstance(data.get("materials"), dict):
        items += list(data["materials"].values())
    for item in items:
        if isinstance(item, dict) and isinstance(item.get("path"), str):
            item["path"] = os.path.relpath(os.path.join(from_dir, item["path"]), to_dir)


def parse_value(text: str) -> Any:
    """A --set value as TOML (numbers, booleans, arrays, quoted strings), else a bare string."""
    try:
        return tomli.loads(f"v = {text}")["v"]
    except (tomli.TOMLDecodeError, ValueError):  # ValueError: an integer of > 4300 digits
        return text


def apply_override(data: dict, assignment: str, prov: Provenance) -> None:
    """`a.b.c=value`: list items are addressed by index or by their `name`."""
    if "=" not in assignment:
        raise Problems([Problem("--set", assignment, "expected key=value")])
    key, text = assignment.split("=", 1)
    parts = key.strip().split(".")
    node: Any = data
    path: list = []
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        if isinstance(node, list):
            idx = _list_index(node, part)
            if idx is None:
                raise Problems([Problem("--set", key, f"no list item '{part}'")])
            part = idx
        elif not isinstance(node, dict):
            raise Problems([Problem("--set", key, "not a table")])
        path.append(part)
        if last:
            for stale in [k for k in prov if k[: len(path)] == tuple(path)]:
                del prov[stale]  # what the file had there is replaced, items included
            node[part] = parse_value(text.strip())
            _mark(node[part], "--set", tuple(path), prov)
        else:
            if isinstance(node, dict) and part not in node:
                node[part] = {}
            node = node[part]


def _list_index(items: list, part: str) -> int | None:
    if part.lstrip("-").isdigit():
        i = int(part)  # from the end when negative; kept as its index from the start, the
        # index pydantic's errors and the provenance use
        return i % len(items) if -len(items) <= i < len(items) else None
    for i, item in enumerate(items):
        if isinstance(item, dict) and item.get("name") == part:
            return i
    return None


_TAG_KEYS = ("shape", "kind", "name")
_DEFAULT_TAGS = ("solid",)  # a material without `kind` is solid: pydantic names the tag


def field_path(loc: tuple, data: Any, missing: bool = False) -> tuple:
    """The user's field: drop the discriminator tags and union member labels pydantic puts
    into error locations (`constrained-float`, `tuple[...]`, `literal[...]`, `solid`). A key
    the user did not write is kept only as the last part of a `missing` error (`missing`)."""
    out: list = []
    node = data
    tag_dropped = False
    for i, part in enumerate(loc):
        if (
            isinstance(node, dict)
            and not tag_dropped
            and part not in node
            and (any(node.get(k) == part for k in _TAG_KEYS)
                 or (isinstance(part, str) and part is not loc[-1] and "kind" not in node
                     and part in _DEFAULT_TAGS))
        ):
            tag_dropped = True
            continue
        if isinstance(part, str) and part.startswith("function-"):
            continue
        if isinstance(part, str) and node is not None and not isinstance(node, dict):
            continue  # a union member label (`constrained-float`, `tuple[...]`) under a value
        if (isinstance(part, str) and isinstance(node, dict) and part not in node
                and not (missing and i == len(loc) - 1)):
            continue  # a union member label under a table the user wrote (`{r = 1}`)
        tag_dropped = False
        out.append(part)
        if isinstance(node, dict):
            node = node.get(part)
        elif isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
            node = node[part]
        else:
            node = None
    return tuple(out)


def _message(err: dict, root=None, loc: tuple = (), data: Any = None) -> str:
    plain = plain_message(err, root, loc, data)
    if plain is not None:
        return plain
    ctx = err.get("ctx") or {}
    kind = err["type"]
    simple = {
        "greater_than": "must be > {gt}",
        "greater_than_equal": "must be >= {ge}",
        "less_than": "must be < {lt}",
        "less_than_equal": "must be <= {le}",
    }
    if kind in simple:
        return simple[kind].format(**ctx)
    if kind == "extra_forbidden":
        return "unknown key"
    if kind == "missing":
        return "required"
    msg = err["msg"]
    return msg[len("Value error, ") :] if msg.startswith("Value error, ") else msg


def validation_problems(e: ValidationError, data: dict, prov: Provenance, default: str,
                        root=None):
    found: dict[tuple, Problem] = {}  # (file, field) -> its one line, in order
    wrong_type: dict[tuple, list[str]] = {}  # (file, field) -> "must be ..." of each member
    for err in e.errors():
        loc = field_path(tuple(err["loc"]), data, missing=err["type"] == "missing")
        if err["type"] in ("union_tag_invalid", "union_tag_not_found"):
            loc = (*loc, tag_name(err.get("ctx")))
        field = ".".join(str(p) for p in loc)
        file = origin(prov, loc, default)
        key, message = (file, field), _message(err, root, loc, data)
        kinds = wrong_type.get(key)
        if kinds is None:
            if key in found:
                continue  # a union member refused what the value is: the first line says it
            found[key] = Problem(file, field, message)
            if err["type"] in _WRONG_TYPE:
                wrong_type[key] = [message]
        elif err["type"] in _WRONG_TYPE:
            kinds.append(message)  # one union member after another: "a number or an array"
        else:
            # a member that takes this kind of value refused it: its line is the one
            del wrong_type[key]
            found[key] = Problem(file, field, message)
    for (file, field), kinds in wrong_type.items():
        if len(kinds) > 1:
            words = [k.removeprefix("must be ") for k in dict.fromkeys(kinds)]
            found[(file, field)] = Problem(file, field, "must be " + " or ".join(words))
    return _one_line_per_typo(list(found.values()))


# errors that say the value is not of a union member's type (the member does not apply)
_WRONG_TYPE = frozenset({
    "model_type", "model_attributes_type", "dict_type", "list_type", "tuple_type",
    "float_type", "float_parsing", "int_type", "int_parsing", "string_type", "bool_type",
    "bool_parsing", "literal_error",
})


def _one_line_per_typo(problems: list[Problem]) -> list[Problem]:
    """A misspelled key is one mistake: its "unknown key (did you mean camera?)" line says
    it all, so the "required" lines of the key it meant (or of the keys inside it:
    `camera.eye: required`) are dropped. A misspelled `kind` read the table as the default
    kind (a material without one is solid), whose "unknown key" lines for the other kind's
    keys are dropped too. And a value is one mistake: the lines inside a field already
    refused (a union's other member: `reflectance = []` is neither a number nor three
    numbers) are dropped."""
    meant, kinds = [], []
    for p in problems:
        m = re.search(r"unknown key \(did you mean (.+)\?\)$", p.message)
        if m:
            parent = p.field.rpartition(".")[0]
            meant.append((p.file, f"{parent}.{m.group(1)}" if parent else m.group(1)))
            if m.group(1) == "kind":
                kinds.append((p.file, parent, p.field))
    refused = {(p.file, p.field) for p in problems}

    def covered(p: Problem) -> bool:
        if p.message == "required" and any(
                p.file == file and (p.field == key or p.field.startswith(key + "."))
                for file, key in meant):
            return True
        if p.message.startswith("unknown key") and any(
                p.file == file and p.field != typo and p.field.startswith(parent + ".")
                for file, parent, typo in kinds):
            return True
        parts = p.field.split(".")
        return any((p.file, ".".join(parts[:n])) in refused for n in range(1, len(parts)))

    return [p for p in problems if not covered(p)]


def _technique_agrees(data: dict, technique: str, prov: Provenance) -> None:
    """--technique and a --set of the technique's name (`technique.name=...`, or a whole
    `technique={...}`) must agree: the --set one silently won. A --set table without a
    name takes --technique's (not the default technique's)."""
    current = data.get("technique")
    if not isinstance(current, dict):
        return  # not a table: the model says what it must be
    if "name" not in current:
        current["name"] = technique
        _mark(current["name"], "--technique", ("technique", "name"), prov)
    elif current["name"] != technique:
        name = current["name"]
        shown = f'"{name}"' if isinstance(name, str) else str(name)
        shown = shown if len(shown) <= 40 else shown[:37] + "..."
        raise Problems([Problem("--set", "technique.name", (
            f"{shown} disagrees with --technique {technique} (give the technique once)"))])


def load_document(
    path: str,
    overrides: list[str] | tuple = (),
    technique: str | None = None,
    *,
    model: type[BaseModel],
    default_technique: str,
    checks: Callable[[Any, str, Provenance, str], list[Problem]] | None = None,
) -> tuple[Any, Provenance]:
    """Read, merge, override and validate a scene file against `model` (the scene model with
    the technique union, built above config); then `checks(cfg, path, prov, display)` for
    what a schema cannot express. Raises Problems."""
    prov: Provenance = {}
    display = os.path.relpath(path) if not os.path.relpath(path).startswith("..") else path
    data = load_raw(path, prov)
    if technique is not None:
        current = data.get("technique")
        if not (isinstance(current, dict) and current.get("name") == technique):
            data["technique"] = {"name": technique}
            note_dropped_parameters(current, technique, model)
            _mark(data["technique"], "--technique", ("technique",), prov)
    for assignment in overrides:
        apply_override(data, assignment, prov)
    if technique is not None:
        _technique_agrees(data, technique, prov)
    current = data.get("technique")
    if isinstance(current, dict) and "name" not in current:
        current["name"] = default_technique  # a scene that names none: the default
    try:
        cfg = model.model_validate(data)
    except ValidationError as e:
        problems = validation_problems(e, data, prov, display, model)
        raise Problems(by_name(problems, overrides, data)) from None
    problems = limit_problems(cfg, prov, display, path, memory=memory_problem)
    if not problems and checks is not None:
        problems = checks(cfg, path, prov, display)
    if problems:
        raise Problems(by_name(problems, overrides, data))
    return cfg, prov
