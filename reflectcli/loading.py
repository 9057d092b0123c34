"""Scene files in: the config loader (config/) given the registry's technique union and the
checks that need scene geometry (scene/checks.py). This is the `load_config` to call."""

from __future__ import annotations

from .config.load import Provenance, load_document
from .config.scene import SceneConfig
from .scene.checks import semantic_problems
from .techniques.registry import DEFAULT_TECHNIQUE, scene_model


def load_config(path: str, overrides: list[str] | tuple = (),
                technique: str | None = None) -> tuple[SceneConfig, Provenance]:
    """Read, merge, override and validate a scene file. Raises Problems."""
    return load_document(path, overrides, technique, model=scene_model(),
                         default_technique=DEFAULT_TECHNIQUE, checks=semantic_problems)
