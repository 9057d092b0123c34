"""Shared fixtures: shipped scenes, and rendering a scene frame in-process."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from reflectcli.camera import camera_from_config
from reflectcli.loading import load_config
from reflectcli.scene.build import build_scene
from reflectcli.techniques.registry import TECHNIQUES

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def render_frame(scene: str | Path, technique: str | None = None, frame: int = 0,
                 overrides: tuple[str, ...] = ()):
    """Render one frame of a scene file in-process: (Frame, Scene)."""
    path = Path(scene) if Path(scene).suffix else SCENES / f"{scene}.toml"
    cfg, _ = load_config(str(path), list(overrides), technique)
    built = build_scene(cfg, str(path))
    cls = TECHNIQUES[cfg.technique.name]
    tech = cls(cfg.technique, 2)
    return tech.render(tech.prepare(built), frame, camera_from_config(cfg.camera, frame)), built


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """PSNR in dB for linear images with peak 1 over the given pixels (N, 3)."""
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(1.0 / mse)


@pytest.fixture
def render():
    return render_frame


@pytest.fixture
def scenes_dir() -> Path:
    return SCENES
