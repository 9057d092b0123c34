"""Rewrite docs/scene-reference.md from the pydantic models."""

from pathlib import Path

from reflectcli.reference import scene_reference

Path(__file__).resolve().parents[1].joinpath("docs", "scene-reference.md").write_text(
    scene_reference() + "\n")
