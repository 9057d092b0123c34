"""The newcomer's path: the schema and the scene reference, bringing one's own mesh and
texture (with `fit`), and the notices a first run needs."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np

from reflectcli.output.exr import read_exr
from reflectcli.reference import scene_reference

from .common import TINY, chdir, invoke, write

ROOT = Path(__file__).resolve().parents[2]


def test_schema_prints_the_json_schema_of_scene_files():
    result = invoke("schema")
    assert result.exit_code == 0
    schema = json.loads(result.stdout)
    assert {"scene", "camera", "objects", "mirrors", "technique"} <= set(schema["properties"])


def test_scene_reference_is_current_and_documents_every_key():
    text = (ROOT / "docs" / "scene-reference.md").read_text()
    assert text == scene_reference() + "\n", "run scripts/scene_reference.py"
    for key in ("`fov_y`", "`reflectance`", "`fit`", "`subdivisions`", "`log`"):
        assert key in text
    assert "ARCHITECTURE.md" not in (ROOT / "README.md").read_text()


def test_own_content_example_renders_and_fit_places_the_mesh(tmp_path, caplog):
    caplog.set_level(logging.INFO, logger="reflect")
    example = ROOT / "docs" / "examples" / "own-content.toml"
    result = invoke("render", example, "--out", tmp_path, "--frames", "0",
                    "--set", "camera.width=32", "--set", "camera.height=24")
    assert result.exit_code == 0, result.output
    assert "8640 triangles, bounds" in caplog.text
    channels, _ = read_exr(str(tmp_path / "own-content" / "raytrace" / "frame_0000.exr"))
    assert np.isfinite(channels["R"]).all()
    from reflectcli.loading import load_config
    from reflectcli.scene.build import object_mesh

    cfg, _ = load_config(str(example))
    (model,) = [o for o in cfg.objects if o.name == "model"]
    points = object_mesh(model, str(example)).corners.reshape(-1, 3)
    lo, hi = points.min(axis=0), points.max(axis=0)
    assert np.isclose((hi - lo).max(), 1.2)
    assert np.allclose((lo + hi) / 2, [0.0, 1.0, 0.0])


def test_switched_technique_says_it_falls_back(tmp_path, caplog):
    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "raytrace"\nmax_depth = 3\n')
    with chdir(tmp_path):
        result = invoke("render", scene, "--out", tmp_path / "o", "--technique", "rerender")
    assert result.exit_code == 0
    assert "rerender uses its own defaults" in caplog.text and "max_depth" in caplog.text


def test_frames_past_the_end_warn(tmp_path):
    scene = write(tmp_path, "s.toml", TINY)
    with chdir(tmp_path):
        result = invoke("render", scene, "--out", tmp_path / "o", "--frames", "0:5",
                        "--technique", "raster")
    assert result.exit_code == 0
    assert "the camera path has 1 frame(s)" in result.output


def test_compare_warns_on_srgb_png_against_linear_exr(tmp_path):
    scene = write(tmp_path, "s.toml", TINY)
    with chdir(tmp_path):
        invoke("render", scene, "--out", tmp_path / "o", "--technique", "raster", "--preview")
    folder = tmp_path / "o" / "tiny" / "raster"
    result = invoke("compare", folder / "frame_0000.exr", folder / "frame_0000.png")
    assert "is sRGB-encoded and" in result.output and "linear" in result.output


def test_textured_mesh_without_uvs_warns(tmp_path, caplog):
    example = ROOT / "docs" / "examples" / "own-content.toml"
    result = invoke("validate", example)
    assert result.exit_code == 0 and "texture coordinates" not in caplog.text
    text = example.read_text().replace('material = "clay"', 'material = "picture"')
    text = text.replace("../../scenes/", str(ROOT / "scenes") + "/")
    scene = write(tmp_path, "s.toml", text)
    assert invoke("validate", scene).exit_code == 0
    assert "objects.model:" in caplog.text and "has no texture coordinates" in caplog.text
