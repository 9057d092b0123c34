"""`reflect validate`: a whole scene, a bench file, or a section file / technique preset
(camera, mirrors, technique, ...).

A scene goes through every check `render` runs short of rendering (the scene build
included), so the two always agree. A file with `[scene]` is a scene. A file without one is
an include fragment, section file or preset, whatever sections it holds (`[camera]` and
`[materials]` are a common fragment): each section is checked as a scene would check it, and
stderr says that `render` refuses the file by itself (`scene: required`), so that it is
the scene including it that renders (and validates) as a whole. Checked as a scene, a fragment
failed on `scene: required` and on references to what the including scene defines.
"""

from __future__ import annotations

import os

from pydantic import ValidationError, create_model

from .config.base import Strict
from .config.files import display_path
from .config.load import load_raw, validation_problems
from .errors import Problem, Problems
from .loading import load_config


def _check_output_folder(cfg, display: str, frames=None, prov: dict | None = None) -> None:
    """The checks render makes of its output folder, short of creating it (a folder is
    made and removed where it would go: paths.check_writable). `prov`: load_config's, so
    that a line names the file `output.dir` or `output.log` came from, as render's does."""
    from .api import check_output_root
    from .config.load import origin
    from .output.identity import check_same_overrides, logged_rows
    from .output.paths import check_links, check_writable, inside

    dir_source = origin(prov or {}, ("output", "dir"), display)
    log_source = origin(prov or {}, ("output", "log"), display)
    check_output_root(cfg.output.dir, dir_source, "output.dir", cfg)
    folder = inside(inside(cfg.output.dir, cfg.scene.name, display, "scene.name"),
                    cfg.technique.name, display)
    inside(folder, cfg.output.log, log_source, "output.log")
    check_links(cfg.output.dir, folder, cfg.output.log, dir_source, "output.dir", log_source,
                frames)
    check_writable(folder, dir_source, "output.dir")
    # render (no --set: validate takes none) refuses a folder of other overrides' frames
    check_same_overrides(logged_rows(os.path.join(folder, cfg.output.log)), [], folder,
                         display)


def validate_file(path: str) -> str:
    """Raise Problems for everything wrong with the file; else what it was checked as."""
    prov: dict = {}
    display = display_path(path)
    raw = load_raw(path, prov)
    if not raw:
        raise Problems([Problem(display, "", "empty file: no keys (a scene needs [scene] "
                                             "and [camera])")])
    if "bench" in raw:
        from .bench.runner import load_bench

        plan = load_bench(path)
        return f"bench file, {len(plan.jobs)} run(s)"
    from .techniques.registry import scene_model

    fields = scene_model().model_fields
    if "scene" in raw or not set(raw) <= set(fields):  # unknown keys: the scene's lines
        cfg, prov = load_config(path)
        from .scene.build import build_scene

        build_scene(cfg, path, prov)
        from .api import OpenedScene

        opened = OpenedScene(cfg, path, provenance=prov)
        # render's frames, all of them
        _check_output_folder(cfg, display, opened.frames(), prov)
        opened.check_cache()  # the default cache, beside the scene
        return "scene"
    section = create_model("Section", __base__=Strict,
                           **{key: (fields[key].annotation, fields[key]) for key in raw})
    try:
        section.model_validate(raw)
    except ValidationError as e:
        raise Problems(validation_problems(e, raw, prov, display, section)) from None
    return (f"section or include file ({', '.join(raw)}): it has no [scene], so it cannot be "
            "rendered by itself (render refuses it: scene: required); validate the scene that "
            "includes it")
