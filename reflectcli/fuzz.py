"""Fuzzing the input path: mutate the bundled scenes, then hold `validate` and `render` to
their promises on each mutant: no traceback, no hang, the two agree, a refusal writes
nothing and says each problem in one line, and nothing names internal files or classes.

Used by tests/hardening/test_fuzz.py (a small budget) and `make fuzz` (scripts/fuzz.py).
"""

from __future__ import annotations

import copy
import json
import math
import os
import random
import re
import shutil
import traceback
from pathlib import Path

SCENES = Path(__file__).resolve().parents[1] / "scenes"

POOL = [0, -1, 1, 2, 3, 0.5, -0.0, 1e16, -1e16, 1e-30, 5e-324, 1e308, math.inf, -math.inf,
        math.nan, 10**7, 2**63 - 1, -(2**63), "", "..", ".", "../x", "/dev/zero", "x",
        "frame_0001.exr", "a\0b", "sphere", "quad", "raster", "dprm", True, False, [], {},
        [0, 0, 0], [1e16, 0, 0], [1, 1], [[0, 0, 0]] * 4, [0.0, 0.0], {"x": 1}, "/tmp",
        [[0, 0], [1, 0]], 4096, 100000, -5, 0.001, 180, 1e-7]


def _technique_names() -> list[str]:
    """Every registered technique (screen-space and distance-map ones included)."""
    from .techniques.registry import PARAMS

    return sorted(PARAMS)


TECHNIQUES = _technique_names()
_BARE = re.compile(r"^[A-Za-z0-9_-]+$")
# what a message must never show
_INTERNAL = re.compile(r"Traceback|<warm-up>|\b[A-Z]\w*(Params|Config|Object|Mirror|Material|"
                       r"Light|Section)\b|reflectcli/|site-packages|Input should")


def base_scenes() -> list[tuple[str, dict]]:
    """(name, raw table) of every bundled scene, file paths made absolute, images small."""
    import tomli

    out = []
    for path in sorted(SCENES.glob("*.toml")):
        data = tomli.loads(path.read_text())
        for key in ("objects", "mirrors"):
            for item in data.get(key, []):
                if isinstance(item.get("path"), str):
                    item["path"] = str(SCENES / item["path"])
        for mat in data.get("materials", {}).values():
            if isinstance(mat.get("path"), str):
                mat["path"] = str(SCENES / mat["path"])
        cam = data.setdefault("camera", {})
        cam["width"], cam["height"] = 16, 12
        for item in data.get("objects", []):  # the same code at a fraction of the cost
            if item.get("shape") == "clutter":
                item["triangles"] = 5000
        out.append((path.stem, data))
    return out


def _paths(node, prefix=()):
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, (*prefix, i))


def _get(node, path):
    for p in path:
        node = node[p]
    return node


def _numbers(node, prefix=()):
    for path in _paths(node, prefix):
        value = _get(node, path)
        if isinstance(value, (int, float)) and not isinstance(value, bool) and path:
            yield path


def _vectors(node):
    for path in _paths(node):
        value = _get(node, path)
        if (isinstance(value, list) and len(value) == 3
                and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in value)):
            yield path


def gentle(data: dict, rng: random.Random) -> None:
    """An edit that often stays valid: nudge a number, make two points coincide, switch the
    technique; what reaches the kernels."""
    op = rng.random()
    numbers = list(_numbers(data))
    vectors = list(_vectors(data))
    if op < 0.5 and numbers:
        path = rng.choice(numbers)
        parent, key = _get(data, path[:-1]), path[-1]
        value = parent[key]
        if isinstance(value, int):
            parent[key] = rng.choice([0, 1, 2, 3, 4, value * 2, value + 1, max(value - 1, 0)])
        else:
            parent[key] = value * rng.choice([0.0, -1.0, 2.0, 0.5, 1e-6, 1e-3, 1e3, 1e5]) + \
                rng.choice([0.0, 0.0, 1e-9, -1e-9])
    elif op < 0.75 and len(vectors) > 1:
        a, b = rng.sample(vectors, 2)
        parent = _get(data, a[:-1])
        parent[a[-1]] = list(_get(data, b))
    else:
        name = rng.choice(TECHNIQUES)
        data["technique"] = {"name": name}
        extra = {"raytrace": {"max_depth": [0, 1, 8], "samples": [1, 2]},
                 "rerender": {"max_depth": [0, 1, 4], "clip": ["none", "plane", "oblique"]},
                 "envmap": {"map": ["cube", "sphere"], "resolution": [4, 8, 16],
                            "parallax": ["none", "box"]},
                 "dprm": {"maps": [{"resolution": 8}, {"resolution": 16, "count": 4,
                                                       "per_frame": 2}]},
                 "distmap": {"resolution": [4, 8, 16], "layers": [1, 2], "steps": [1, 4, 16],
                             "refine_steps": [0, 4], "update": ["once", "every", 2],
                             "faces_per_frame": [1, 6]},
                 "ssr": {"march": ["linear", "dda", "hiz"], "thickness": [0.01, 0.1, 5.0],
                         "stride": [1.0, 4.0], "max_steps": [1, 64], "resolve": ["pixel",
                                                                                "surface"],
                         "fallback": ["none", "envmap", "rerender"]},
                 "ppr": {"fill": [True, False], "resolve": ["pixel", "surface"],
                         "fallback": ["none", "envmap", "rerender"]},
                 "virtual": {}, "raster": {}}.get(name, {})
        for key, values in extra.items():
            if rng.random() < 0.6:
                data["technique"][key] = copy.deepcopy(rng.choice(values))


def mutate(data: dict, rng: random.Random, steps: int | None = None) -> dict:
    """1-3 random edits: replace, delete, add a key, scale a number, duplicate an item,
    change a tag, switch the technique; half the time gentle edits only."""
    data = copy.deepcopy(data)
    if rng.random() < 0.5:
        for _ in range(steps if steps is not None else rng.randint(1, 3)):
            gentle(data, rng)
        return data
    for _ in range(steps if steps is not None else rng.randint(1, 3)):
        paths = [p for p in _paths(data) if p]
        if not paths:
            break
        path = rng.choice(paths)
        parent = _get(data, path[:-1])
        key = path[-1]
        op = rng.random()
        if op < 0.35:
            parent[key] = copy.deepcopy(rng.choice(POOL))
        elif op < 0.5:
            del parent[key]
        elif op < 0.6 and isinstance(parent, dict):
            name = rng.choice([str(key)[:-1] or "k", str(key) + "s", "fov", "colour", "x"])
            parent[name] = copy.deepcopy(rng.choice(POOL))
        elif op < 0.75:
            value = parent[key]
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                factor = rng.choice([0, -1, 1e16, 1e-30, 1e-300, 1000, 0.5])
                parent[key] = value * factor if math.isfinite(value * factor) else 1e308
            else:
                parent[key] = copy.deepcopy(rng.choice(POOL))
        elif op < 0.85 and isinstance(parent, list):
            parent.insert(key, copy.deepcopy(parent[key]))
        elif op < 0.93:
            data["technique"] = {"name": rng.choice(TECHNIQUES)}
            if rng.random() < 0.5:
                data["technique"][rng.choice(["max_depth", "resolution", "samples",
                                              "map", "maps", "march", "thickness", "layers",
                                              "steps", "update", "fallback", "resolve"])] = \
                    copy.deepcopy(rng.choice(POOL))
        else:
            tags = {"shape": ["quad", "sphere", "box", "room", "cylinder", "extrusion",
                              "cap", "mesh", "teapot", "rectangle", "clutter", "torus"],
                    "kind": ["solid", "checker", "texture", "point", "directional"]}
            if isinstance(parent, dict):
                for tag, values in tags.items():
                    if tag in parent:
                        parent[tag] = rng.choice(values)
    return data


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def _key(k) -> str:
    k = str(k)
    return k if _BARE.match(k) else json.dumps(k)


def to_toml(data: dict) -> str:
    return "".join(f"{_key(k)} = {_value(v)}\n" for k, v in data.items())


def mangle_text(text: str, rng: random.Random) -> str:
    """Byte-level damage: truncate, drop a line, insert a character."""
    op = rng.random()
    if op < 0.4:
        return text[: rng.randrange(len(text) + 1)]
    lines = text.splitlines(keepends=True)
    if op < 0.7 and lines:
        del lines[rng.randrange(len(lines))]
        return "".join(lines)
    at = rng.randrange(len(text) + 1)
    junk = rng.choice(["[", "]", "{", "=", '"', "\n", ",", "\\", "\x00", "é"])
    return text[:at] + junk + text[at:]


def one_case(seed: int, bases=None) -> tuple[str, str]:
    """(name, TOML text) of the mutant for `seed`."""
    rng = random.Random(seed)
    bases = bases or base_scenes()
    name, data = bases[rng.randrange(len(bases))]
    text = to_toml(mutate(data, rng))
    if rng.random() < 0.1:
        text = mangle_text(text, rng)
    return name, text


def _messages_ok(problems) -> str | None:
    for p in problems:
        line = str(p)
        if "\n" in line or _INTERNAL.search(line):
            return f"bad message: {line!r}"
    return None


def check(scene_path: str, out: str, cache: str, render: bool = True) -> dict:
    """Run validate and render on one file; a dict whose `failure` is None when every promise
    holds ("traceback", "disagree", "wrote", "message" otherwise)."""
    from . import api
    from .errors import Problems
    from .validate import RenderOptions, validate_file

    result: dict = {"failure": None}
    # validated with the options it is rendered with: the output folder, frame and cache
    # render uses (validate's defaults would judge ./out, every frame and the scene's cache)
    options = RenderOptions(out=out, frames="0", threads=1, cache=cache) if render else None
    try:
        kind = validate_file(scene_path, options).kind
        result["validate"] = "ok"
    except Problems as e:
        kind = None
        result["validate"] = str(e).splitlines()[0]
        bad = _messages_ok(e.problems)
        if bad:
            result.update(failure="message", detail=bad)
            return result
    except Exception:
        result.update(failure="traceback", detail="validate: " + traceback.format_exc())
        return result
    if not render:
        return result
    shutil.rmtree(out, ignore_errors=True)
    try:
        api.render(scene_path, out=out, frames="0", threads=1, cache=cache)
        result["render"] = "ok"
    except Problems as e:
        result["render"] = str(e).splitlines()[0]
        bad = _messages_ok(e.problems)
        if bad:
            result.update(failure="message", detail=bad)
        elif os.path.exists(out) and any(files for _, _, files in os.walk(out)):
            result.update(failure="wrote", detail="render refused but wrote files")
    except Exception:
        result.update(failure="traceback", detail="render: " + traceback.format_exc())
        return result
    if result["failure"] is None and kind == "scene" and (
            (result["validate"] == "ok") != (result["render"] == "ok")):
        result.update(failure="disagree",
                      detail=f"validate: {result['validate']} / render: {result['render']}")
    if result["failure"] is None and kind not in (None, "scene") and result["render"] == "ok":
        result.update(failure="disagree", detail=f"validate called it a {kind} yet it renders")
    return result
