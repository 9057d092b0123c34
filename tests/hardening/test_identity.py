"""Outputs say what made them: --set overrides are never silently mixed into a folder of
frames made without them, --resume skips only frames made from the same scene and
parameters (and writes missing previews), timings rows carry a run id, and
reflect:scene_hash identifies the scene alone."""

from __future__ import annotations

import json

from reflectcli.output.exr import read_exr
from reflectcli.output.identity import matches
from reflectcli.output.log import read_jsonl

from .common import TINY, assert_one_line, chdir, invoke, write

WALK = TINY.replace("height = 12\n", "height = 12\n[camera.path]\nframes = 3\n"
                    "keys = [{ eye = [0.0, 1.0, 3.0], target = [0.0, 0.5, 0.0] },\n"
                    "        { eye = [1.0, 1.0, 3.0], target = [0.0, 0.5, 0.0] }]\n")


def render(scene, out, *args):
    result = invoke("render", scene, "--out", out, *args)
    assert result.exit_code == 0, result.output
    return result


def test_set_does_not_silently_overwrite_frames_made_without_it(tmp_path):
    scene = write(tmp_path, "s.toml", TINY)
    with chdir(tmp_path):
        render(scene, tmp_path / "o", "--frames", "0")
        folder = tmp_path / "o" / "tiny" / "raytrace"
        before = (folder / "frame_0000.exr").read_bytes()
        result = invoke("render", scene, "--out", tmp_path / "o", "--set",
                        "technique.max_depth=0")
        assert_one_line(result, "--set:", "other overrides (no --set)")
        assert (folder / "frame_0000.exr").read_bytes() == before
        render(scene, tmp_path / "o", "--frames", "0")  # the same (no) overrides: fine


def test_resume_rerenders_frames_of_other_parameters_and_writes_missing_previews(tmp_path):
    scene = write(tmp_path, "s.toml", WALK)
    with chdir(tmp_path):
        render(scene, tmp_path / "o")
        folder = tmp_path / "o" / "tiny" / "raytrace"
        write(tmp_path, "s.toml", WALK + '\n[technique]\nname = "raytrace"\nmax_depth = 0\n')
        result = render(scene, tmp_path / "o", "--resume", "--preview")
        assert "wrote 3 frame(s)" in result.output  # stored parameters differ: not skipped
        for png in folder.glob("*.png"):
            png.unlink()
        result = render(scene, tmp_path / "o", "--resume", "--preview")
        assert "wrote 0 frame(s)" in result.output and "3 skipped" in result.output
        assert sorted(p.name for p in folder.glob("*.png")) == [
            "frame_0000.png", "frame_0001.png", "frame_0002.png"]


def test_run_id_and_scene_hash_of_the_scene_alone(tmp_path):
    scene = write(tmp_path, "s.toml", TINY)
    with chdir(tmp_path):
        render(scene, tmp_path / "o", "--frames", "0")
        render(scene, tmp_path / "o", "--frames", "0", "--technique", "raster")
    rows = {}
    hashes = {}
    for technique in ("raytrace", "raster"):
        folder = tmp_path / "o" / "tiny" / technique
        (rows[technique],) = read_jsonl(str(folder / "timings.jsonl"))
        _, attrs = read_exr(str(folder / "frame_0000.exr"))
        hashes[technique] = attrs["reflect:scene_hash"]
        assert json.loads(attrs["reflect:parameters"])["name"] == technique
    assert hashes["raytrace"] == hashes["raster"]  # an image pairs with its reference
    assert rows["raytrace"]["run_id"] != rows["raster"]["run_id"]
    assert len(rows["raster"]["run_id"]) == 12


def test_resume_takes_a_parameter_added_since_as_its_default(tmp_path):
    """Frames logged before a parameter existed (their rows do not name it) are skipped by
    --resume while it is at its default, and rendered again once it is not."""
    scene = write(tmp_path, "s.toml", WALK)
    with chdir(tmp_path):
        render(scene, tmp_path / "o")
        log = tmp_path / "o" / "tiny" / "raytrace" / "timings.jsonl"
        rows = read_jsonl(str(log))
        for row in rows:  # as a run before raytrace had `embree` wrote them
            del row["parameters"]["embree"]
        log.write_text("".join(json.dumps(row) + "\n" for row in rows))
        result = render(scene, tmp_path / "o", "--resume")
        assert "wrote 0 frame(s)" in result.output and "3 skipped" in result.output
    row = {"scene_hash": "h", "parameters": {"name": "raytrace", "max_depth": 4}}
    defaults = {"name": "raytrace", "max_depth": 4, "embree": "robust"}
    assert matches(row, "h", dict(defaults), defaults)
    assert not matches(row, "h", dict(defaults, embree="fast"), defaults)
    assert not matches(row, "h", dict(defaults))  # without the defaults: as before
    nested = {"scene_hash": "h", "parameters": {"a": {"b": 1}}}
    assert matches(nested, "h", {"a": {"b": 1, "c": 2}}, {"a": {"b": 0, "c": 2}})
