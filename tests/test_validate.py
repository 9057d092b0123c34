"""`reflect validate` takes render's options and refuses, in render's words, whatever render
would refuse with them before writing anything, and writes nothing itself: no output
folder, no cache folder, no lock, no log."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from hardening.common import TINY, assert_one_line, chdir, invoke, write

# a scene that passes validate as it is: what refuses it below is the options alone
PATH = ('[camera.path]\nframes = 4\n'
        'keys = [{ eye = [0, 1, 3], target = [0, 0.5, 0] }, '
        '{ eye = [1, 1, 3], target = [0, 0.5, 0] }]\n')
SCENE = TINY.replace("height = 12\n", "height = 12\n" + PATH)
FOLDER = Path("o") / "tiny" / "raytrace"  # the frame folder of `--out o`


def listing(root: Path) -> list[tuple[str, str, int]]:
    """Every entry under `root` (hidden ones, links and folders too): path, kind, size."""
    found = []
    for folder, dirs, files in os.walk(root):
        for name in dirs + files:
            path = os.path.join(folder, name)
            st = os.lstat(path)
            kind = ("link" if os.path.islink(path) else "dir" if os.path.isdir(path)
                    else "file")
            found.append((os.path.relpath(path, root), kind, st.st_size if kind == "file"
                          else 0))
    return sorted(found)


def refused_alike(root: Path, scene: Path, *args: str, needles: tuple = ()) -> str:
    """validate and render, given the same options, refuse in the same one line (exit 2);
    neither leaves anything on disk."""
    before = listing(root)
    line = assert_one_line(invoke("validate", scene, *args), *needles)
    assert listing(root) == before, "validate wrote"
    assert assert_one_line(invoke("render", scene, *args)) == line
    assert listing(root) == before, "render wrote"
    return line


def make_afile(tmp_path: Path) -> None:
    (tmp_path / "afile").write_text("a file, not a folder")


def make_link_at_a_frame(tmp_path: Path) -> None:
    (tmp_path / FOLDER).mkdir(parents=True)
    (tmp_path / "victim.txt").write_text("kept")
    (tmp_path / FOLDER / "frame_0002.exr").symlink_to(tmp_path / "victim.txt")


def make_folder_at_a_frame(tmp_path: Path) -> None:
    (tmp_path / FOLDER / "frame_0003.exr").mkdir(parents=True)


def make_scene_folder_link(tmp_path: Path) -> None:
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "tiny").symlink_to(tmp_path / "elsewhere")


def make_hard_linked_log(tmp_path: Path) -> None:
    (tmp_path / FOLDER).mkdir(parents=True)
    (tmp_path / "victim.txt").write_text("one line\n")
    os.link(tmp_path / "victim.txt", tmp_path / FOLDER / "timings.jsonl")


def make_frames_of_other_overrides(tmp_path: Path) -> None:
    """A frame folder as a render with `--set camera.width=8` leaves it (no render needed:
    the row and the frame's name are what the check reads)."""
    (tmp_path / FOLDER).mkdir(parents=True)
    (tmp_path / FOLDER / "frame_0000.exr").write_bytes(b"a frame")
    row = {"file": "frame_0000.exr", "frame": 0, "overrides": ["camera.width=8"]}
    (tmp_path / FOLDER / "timings.jsonl").write_text(json.dumps(row) + "\n")


def nothing(tmp_path: Path) -> None:
    pass


# render's refusals that depend on its options: (set-up, options, what the line says)
CASES = {
    "set-unknown-key": (nothing, ("--set", "camera.widht=3"),
                        ("--set: camera.widht: unknown key (did you mean width?)",)),
    "set-bad-value": (nothing, ("--set", "camera.width=0"), ("--set: camera.width: must be > 0",)),
    "set-no-equals": (nothing, ("--set", "camera.width"), ("--set: camera.width: expected "
                                                         "key=value",)),
    "set-no-list-item": (nothing, ("--set", "mirrors.nope.reflectance=0.2"),
                         ("--set: mirrors.nope.reflectance: no list item 'nope'",)),
    "set-log-outside": (nothing, ("--set", 'output.log="../x"'), ("--set: output.log:",)),
    "technique-unknown": (nothing, ("--technique", "nope"),
                          ("--technique: unknown technique 'nope'",)),
    "technique-parameter": (nothing, ("--technique", "raster", "--set", "technique.max_depth=2"),
                            ("technique.max_depth",)),
    "technique-capture-no-mirror": (
        nothing, ("--technique", "envmap", "--set", "technique.capture.flor=[0.0, 0.1, 0.0]"),
        ("technique.capture.flor: no mirror of that name",)),
    "frames-outside": (nothing, ("--frames", "4"), ("--frames: '4' selects no frame of 0..3",)),
    "frames-syntax": (nothing, ("--frames", "1_0"),
                      ("--frames: expected N, A:B or A:B:S, got '1_0'",)),
    "frames-empty-range": (nothing, ("--frames", "3:1"), ("--frames: '3:1' selects no frame",)),
    "threads-zero": (nothing, ("--threads", "0"), ("--threads: must be 1..",)),
    "threads-too-many": (nothing, ("--threads", "100000"), ("--threads: must be 1..",)),
    "out-below-a-file": (make_afile, ("--out", "afile/o"),
                         ("--out: cannot write to 'afile/o/tiny/raytrace': Not a directory",)),
    "out-name-too-long": (nothing, ("--out", "o/" + "d" * 300), ("--out: ", "255 bytes")),
    "out-path-too-long": (nothing, ("--out", "/".join(["d" * 200] * 21)),
                          ("--out: ", "4095 bytes")),
    "out-link-at-a-frame": (make_link_at_a_frame, ("--out", "o"),
                            ("--out: ", "frame_0002.exr", "symbolic link")),
    "out-folder-at-a-frame": (make_folder_at_a_frame, ("--out", "o", "--frames", "3"),
                              ("--out: ", "frame_0003.exr", "is a directory")),
    "out-scene-folder-leads-outside": (make_scene_folder_link, ("--out", "o"),
                                       ("--out: 'o/tiny' leads to", "outside o")),
    "out-log-hard-linked": (make_hard_linked_log, ("--out", "o"),
                            ("output.log", "timings.jsonl", "other hard links")),
    "out-frames-of-other-overrides": (
        make_frames_of_other_overrides, ("--out", "o", "--set", "camera.width=16"),
        ("--set: ", "holds frames rendered with other overrides (camera.width=8)")),
    "cache-below-a-file": (make_afile, ("--technique", "dprm", "--cache", "afile/sub"),
                           ("--cache: cannot write to 'afile/sub': Not a directory",)),
}


@pytest.mark.parametrize("case", CASES)
def test_validate_refuses_what_render_refuses_with_the_same_options(tmp_path, case):
    setup, args, needles = CASES[case]
    scene = write(tmp_path, "s.toml", SCENE)
    with chdir(tmp_path):
        assert invoke("validate", scene).output == "ok\n"  # the options are what is wrong
        setup(tmp_path)
        refused_alike(tmp_path, scene, *args, needles=needles)


def test_a_technique_too_big_for_the_scene_is_refused_by_validate_as_by_render(tmp_path,
                                                                              monkeypatch):
    """--technique's maps for this scene's mirrors, past the memory there is."""
    from reflectcli.config import memory

    monkeypatch.setattr(memory, "available_bytes", lambda: 22 << 30)
    scene = write(tmp_path, "s.toml", SCENE)
    with chdir(tmp_path):
        refused_alike(tmp_path, scene, "--technique", "distmap", "--set",
                      "technique.resolution=4096", "--set", "technique.layers=8",
                      needles=("technique: this render needs about", "22.0 GiB is available"))


@pytest.mark.parametrize(("args", "needle"), [
    (("--out", ""), "--out: empty folder name"),
    (("--cache", ""), "--cache: empty folder name"),
    (("--threads", "abc"), "--threads: 'abc' is not a valid integer"),
    (("--out", "afile"), "--out: Directory 'afile' is a file"),
])
def test_argument_errors_are_render_s_with_the_command_named(tmp_path, args, needle):
    scene = write(tmp_path, "s.toml", SCENE)
    make_afile(tmp_path)
    with chdir(tmp_path):
        before = listing(tmp_path)
        line = assert_one_line(invoke("validate", scene, *args), needle)
        assert line == f"reflect validate: {needle}" + line.partition(needle)[2]
        rendered = assert_one_line(invoke("render", scene, *args))
        assert rendered.replace("reflect render: ", "reflect validate: ") == line
        assert listing(tmp_path) == before


def test_validate_with_valid_options_prints_ok_and_writes_nothing(tmp_path):
    # output.dir under a file and a default cache that is a file: both refused as they are,
    # both replaced by the options
    scene = write(tmp_path, "s.toml", SCENE + '\n[output]\ndir = "afile/out"\n')
    make_afile(tmp_path)
    (tmp_path / ".reflect-cache").write_text("a file where the default cache would go")
    with chdir(tmp_path):
        assert_one_line(invoke("validate", scene), "s.toml: output.dir: cannot write to")
        before = listing(tmp_path)
        result = invoke("validate", scene, "--out", "o", "--frames", "1:3", "--technique",
                        "dprm", "--set", "technique.maps.resolution=16", "--set",
                        "camera.width=8", "--cache", "c", "--threads", "1", "--preview",
                        "--resume")
        assert (result.exit_code, result.output) == (0, "ok\n")
        assert listing(tmp_path) == before
        # a frame folder that exists, with a log, a frame and a stale temporary file, is
        # only read: nothing is added, removed or appended to
        make_frames_of_other_overrides(tmp_path)
        stale = tmp_path / FOLDER / ".frame_0003.tmp999999999-12.exr"
        stale.write_bytes(b"half")
        before = listing(tmp_path)
        result = invoke("validate", scene, "--out", "o", "--set", "camera.width=8")
        assert (result.exit_code, result.output) == (0, "ok\n")
        assert listing(tmp_path) == before


def test_validate_warns_as_render_does_of_frames_past_the_path_s_end(tmp_path):
    scene = write(tmp_path, "s.toml", SCENE)
    with chdir(tmp_path):
        result = invoke("validate", scene, "--frames", "0:9", "--out", "o")
    assert result.exit_code == 0
    assert result.stdout == "ok\n"
    assert result.stderr == ("--frames: the camera path has 4 frame(s) (0..3); rendering "
                             "up to frame 3\n")
    assert sorted(os.listdir(tmp_path)) == ["s.toml"]


def test_a_section_file_given_render_options_is_refused(tmp_path):
    section = write(tmp_path, "cam.toml", "[camera]\neye = [0, 1, 3]\ntarget = [0, 0, 0]\n")
    with chdir(tmp_path):
        result = invoke("validate", section)  # as before: ok, with a note
        assert result.exit_code == 0 and result.stdout == "ok\n"
        assert result.stderr.startswith("checked as a section or include file (camera)")
        line = assert_one_line(invoke("validate", section, "--out", "o", "--set",
                                      "camera.width=8"),
                               "cam.toml: scene: required for --out, --set")
        assert "validate the scene that includes it" in line
        assert invoke("validate", section, "--preview", "--resume").exit_code == 0
    assert sorted(os.listdir(tmp_path)) == ["cam.toml"]


def test_a_bench_file_takes_the_options_bench_shares_with_render(tmp_path):
    write(tmp_path, "s.toml", SCENE)
    bench = write(tmp_path, "b.toml", '[bench]\nname = "b"\nframes = "0"\nplots = false\n'
                  '[[runs]]\nscenes = ["s.toml"]\ntechniques = ["raster"]\n')
    make_afile(tmp_path)
    with chdir(tmp_path):
        before = listing(tmp_path)
        result = invoke("validate", bench, "--out", "bo", "--set", "camera.width=8",
                        "--threads", "1")
        assert result.exit_code == 0 and result.stdout == "ok\n", result.output
        for args in (("--out", "afile/o"), ("--set", "camera.width=0"), ("--threads", "0")):
            line = assert_one_line(invoke("validate", bench, *args))
            assert assert_one_line(invoke("bench", bench, *args)) == line
        line = assert_one_line(invoke("validate", bench, "--frames", "0"),
                               "--frames: applies to a scene file, not to the bench file "
                               "b.toml")
        assert "--out, --set, --threads" in line
        assert listing(tmp_path) == before


def test_render_and_validate_share_the_checks(tmp_path, monkeypatch):
    """validate runs render's own checking code (api.open_render, OpenedScene.check_output),
    not a copy of it."""
    from reflectcli import api

    calls = []
    for name in ("open_render",):
        real = getattr(api, name)
        monkeypatch.setattr(api, name, lambda *a, _real=real, _name=name, **k: (
            calls.append(_name), _real(*a, **k))[1])
    real_check = api.OpenedScene.check_output
    monkeypatch.setattr(api.OpenedScene, "check_output", lambda self, *a, **k: (
        calls.append("check_output"), real_check(self, *a, **k))[1])
    scene = write(tmp_path, "s.toml", SCENE)
    with chdir(tmp_path):
        assert_one_line(invoke("validate", scene, "--threads", "0"), "--threads:")
        assert calls == ["open_render", "check_output"]
        calls.clear()
        assert_one_line(invoke("render", scene, "--threads", "0"), "--threads:")
        assert calls == ["open_render", "check_output"]
