"""`reflect validate`: a whole scene, or a section file (camera, mirrors, technique, ...)."""

from __future__ import annotations

import os

from pydantic import TypeAdapter, ValidationError

from .config.load import load_raw, validation_problems
from .errors import Problems
from .loading import load_config


def validate_file(path: str) -> None:
    """Raise Problems for everything wrong with the file; return quietly if it is fine."""
    prov: dict = {}
    raw = load_raw(path, prov)
    display = os.path.relpath(path)
    if "scene" in raw or "camera" in raw and "objects" in raw:
        cfg, _ = load_config(path)
        from .scene.build import build_scene

        build_scene(cfg, path)
        return
    from .techniques.registry import scene_model

    fields = scene_model().model_fields
    problems = []
    for key, value in raw.items():
        if key not in fields:
            from .errors import Problem

            problems.append(Problem(prov.get((key,), display), key, "unknown key"))
            continue
        try:
            TypeAdapter(fields[key].annotation).validate_python(value)
        except ValidationError as e:
            for p in validation_problems(e, value, prov, display):
                p_field = f"{key}.{p.field}" if p.field else key
                problems.append(type(p)(p.file, p_field, p.message))
    if problems:
        raise Problems(problems)
