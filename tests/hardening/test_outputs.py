"""Outputs stay inside the output folder; `cache clear` deletes only reflect's cache files;
temporary files of killed runs are removed; cache files with the right key but wrong content
are recaptured, never trusted."""

from __future__ import annotations

import contextlib
import logging
import os
import subprocess

import numpy as np
import pytest

from reflectcli.output.exr import read_exr_parts, write_exr_parts

from .common import TINY, assert_one_line, chdir, check_bad, files_under, invoke, write


@pytest.mark.parametrize(("override", "field"), [
    ('scene.name=".."', "scene.name"),
    ('scene.name="."', "scene.name"),
    ('output.log="../x"', "output.log"),
    ('output.log="frame_0001.exr"', "output.log"),
    ('output.log="/tmp/x.jsonl"', "output.log"),
])
def test_outputs_stay_inside_the_output_folder(tmp_path, override, field):
    scene = write(tmp_path, "s.toml", TINY)
    with chdir(tmp_path):
        result = invoke("render", scene, "--out", tmp_path / "o", "--set", override)
    assert result.exit_code == 2 and result.output.startswith(f"--set: {field}:"), result.output
    assert sorted(os.listdir(tmp_path)) == ["s.toml"]


def test_log_named_like_a_frame_in_the_file(tmp_path):
    scene = write(tmp_path, "s.toml", TINY + '\n[output]\nlog = "frame_0000.exr"\n')
    with chdir(tmp_path):
        check_bad(scene, "s.toml: output.log:")


@pytest.mark.parametrize("name", ["timings-summary.json", "Timings-Summary.JSON"])
def test_log_named_like_the_summary_is_refused(tmp_path, name):
    # the summary, written last, replaced every frame's row
    scene = write(tmp_path, "s.toml", TINY + f'\n[output]\nlog = "{name}"\n')
    with chdir(tmp_path):
        line = check_bad(scene, "s.toml: output.log:", "timings summary")
    assert "timings-summary.json" in line


@pytest.mark.parametrize("name", ["timings.jsonl", "frame_0000.exr", "frame_0000.png",
                                  "timings-summary.json"])
def test_a_link_at_an_output_name_is_refused_and_never_written_through(tmp_path, name):
    # a linked log once had its target's last line cut and a row appended, exit 0
    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "raster"\n'
                  '[output]\ndir = "o"\n')
    victim = write(tmp_path, "victim.txt", "line1\nline2 no newline")
    folder = tmp_path / "o" / "tiny" / "raster"
    folder.mkdir(parents=True)
    (folder / name).symlink_to(victim)
    field = "output.log" if name == "timings.jsonl" else "output.dir"
    with chdir(tmp_path):
        line = assert_one_line(invoke("validate", scene), f"s.toml: {field}:",
                               f"{folder.relative_to(tmp_path) / name}", "symbolic link")
        assert assert_one_line(invoke("render", scene, "--preview")) == line
        via_out = assert_one_line(invoke("render", scene, "--out", "o"), "symbolic link")
        assert via_out == line if field == "output.log" else via_out.startswith("--out: ")
    assert victim.read_text() == "line1\nline2 no newline"
    assert os.listdir(folder) == [name]


def test_a_scene_folder_leading_outside_the_output_folder_is_refused(tmp_path):
    # frames once landed in the folder a link under the output folder pointed to
    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "raster"\n'
                  '[output]\ndir = "o"\n')
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "tiny").symlink_to(tmp_path / "elsewhere")
    with chdir(tmp_path):
        line = assert_one_line(invoke("validate", scene), "s.toml: output.dir:",
                               "o/tiny", "outside o")
        assert assert_one_line(invoke("render", scene)) == line
        assert os.listdir("elsewhere") == []
        os.unlink("o/tiny")  # a link that stays inside the output folder is a folder
        os.makedirs("o/real")
        os.symlink("real", "o/tiny")
        assert invoke("validate", scene).exit_code == 0
        result = invoke("render", scene, "--frames", "0")
        assert result.exit_code == 0, result.output
        assert os.listdir("o/real/raster") == ["frame_0000.exr", "timings.jsonl"]


def test_refused_arguments_make_no_folder(tmp_path):
    # --threads 0 once left the bench's lock file, an unusable --cache the frame folder
    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "dprm"\n'
                  '[technique.maps]\nresolution = 16\n')
    bench = write(tmp_path, "b.toml", '[bench]\nname = "b"\nframes = "0"\nplots = false\n'
                  '[[runs]]\nscenes = ["s.toml"]\ntechniques = ["raster"]\n')
    (tmp_path / "afile").write_text("a file, not a folder")
    with chdir(tmp_path):
        assert_one_line(invoke("bench", bench, "--out", "o-th", "--threads", "0"),
                        "--threads:")
        assert_one_line(invoke("render", scene, "--out", "oc", "--cache", "afile/sub"),
                        "--cache: cannot write to 'afile/sub': Not a directory")
        os.rename("afile", ".reflect-cache")  # the default cache, beside the scene
        line = assert_one_line(invoke("validate", scene), "s.toml: cannot write to",
                               ".reflect-cache", "Not a directory")
        assert assert_one_line(invoke("render", scene, "--out", "oc")) == line
        assert invoke("validate", write(tmp_path, "r.toml", TINY)).exit_code == 0  # no maps
    assert sorted(os.listdir(tmp_path)) == [".reflect-cache", "b.toml", "r.toml", "s.toml"]


def test_cache_clear_deletes_only_cache_files(tmp_path):
    cache = tmp_path / "cache"
    cache.mkdir()
    mine = ["envmap-" + "a" * 32 + ".exr", "dprm-" + "0123456789abcdef" * 2 + ".exr"]
    others = ["frame_0000.exr", "notes.exr", "envmap-short.exr", "timings.jsonl"]
    for name in mine + others:
        (cache / name).write_bytes(b"x")
    (cache / f".dprm-{'b' * 32}.tmp999999999-1.exr").write_bytes(b"x")  # a killed capture's
    result = invoke("cache", "clear", "--cache", cache)
    assert result.exit_code == 0 and "removed 2 map(s)" in result.output
    assert sorted(os.listdir(cache)) == sorted(others)


def test_temp_files_of_killed_runs_are_removed(tmp_path):
    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "raster"\n')
    folder = tmp_path / "o" / "tiny" / "raster"
    folder.mkdir(parents=True)
    stale = folder / ".frame_0003.tmp999999999-12.exr"
    stale.write_bytes(b"half")
    live = folder / f".frame_0004.tmp{os.getpid()}-12.exr"  # a running process's: kept
    live.write_bytes(b"half")
    with chdir(tmp_path):
        result = invoke("render", scene, "--out", tmp_path / "o", "--frames", "0")
    assert result.exit_code == 0, result.output
    assert not stale.exists() and live.exists()


def test_cache_file_with_matching_key_but_wrong_content_is_recaptured(tmp_path, caplog):
    caplog.set_level(logging.WARNING, logger="reflect")
    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "dprm"\n'
                  '[technique.maps]\nresolution = 16\n')
    cache = tmp_path / "cache"
    args = ("render", scene, "--out", tmp_path / "o", "--frames", "0", "--cache", cache)
    with chdir(tmp_path):
        assert invoke(*args).exit_code == 0
        (path,) = [p for p in files_under(cache) if p.endswith(".exr")]
        first = (tmp_path / "o" / "tiny" / "dprm" / "frame_0000.exr").read_bytes()
        for damage in ("T", "R"):
            parts = read_exr_parts(path)
            names, channels, attrs = zip(*parts, strict=True)
            bad = [dict(c) for c in channels]
            bad[0][damage] = np.full_like(bad[0][damage], 1e7 if damage == "T" else np.nan)
            write_exr_parts(path, list(zip(names, bad, strict=True)), attrs[0],
                            [dict(a) for a in attrs])
            caplog.clear()
            result = invoke(*args)
            assert result.exit_code == 0, result.output
            assert "damaged" in caplog.text and "recapturing" in caplog.text
            again = (tmp_path / "o" / "tiny" / "dprm" / "frame_0000.exr").read_bytes()
            assert again == first


def test_validate_refuses_an_output_folder_render_could_not_write(tmp_path):
    (tmp_path / "blocker").write_text("a file, not a folder")
    scene = write(tmp_path, "s.toml", TINY + '\n[output]\ndir = "blocker/out"\n')
    with chdir(tmp_path):
        line = assert_one_line(invoke("validate", scene), "s.toml: output.dir:",
                               "cannot write to", "Not a directory")
        assert line == assert_one_line(invoke("render", scene, "--frames", "0"))
        ok = write(tmp_path, "ok.toml", TINY + '\n[output]\ndir = "new/deeper/out"\n')
        assert invoke("validate", ok).exit_code == 0
    assert sorted(os.listdir(tmp_path)) == ["blocker", "ok.toml", "s.toml"]  # nothing made


def test_an_unwritable_folder_is_refused_with_the_reason_the_os_gives(tmp_path, monkeypatch):
    # a folder on a read-only mount was refused as "Permission denied" (os.access is False
    # there too), which sends a user to chmod; the line now gives the OS's own reason
    import errno
    import tempfile

    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS))

    access = os.access
    monkeypatch.setattr(os, "access", lambda path, mode, **kwargs: os.fspath(path) != str(
        tmp_path) and access(path, mode, **kwargs))  # as on a read-only mount
    monkeypatch.setattr(tempfile, "mkdtemp", read_only)
    scene = write(tmp_path, "s.toml", TINY)
    with chdir(tmp_path):
        assert_one_line(invoke("validate", scene), "s.toml: output.dir: cannot write to "
                        "'out/tiny/raytrace': Read-only file system")
    assert sorted(os.listdir(tmp_path)) == ["s.toml"]


def test_an_existing_cache_folder_is_not_refused_as_unwritable(tmp_path, monkeypatch):
    # a complete cache may be read-only: its maps are only read; the check that refuses a
    # cache folder render could not make applies to one that does not exist yet
    from reflectcli import api

    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "dprm"\n')
    (tmp_path / "kept").mkdir()

    def unwritable(folder, source, field):
        raise AssertionError(f"checked {folder} for writing")

    monkeypatch.setattr(api, "check_writable", unwritable)
    api.open_scene(str(scene), cache=str(tmp_path / "kept")).check_cache()
    with pytest.raises(AssertionError):
        api.open_scene(str(scene), cache=str(tmp_path / "new")).check_cache()


def test_a_root_with_dotdot_after_a_link_is_not_refused(tmp_path):
    # `--out build/../out` with build a link elsewhere writes to ./out (paths are joined
    # and normalised); the check once resolved the root through the link and refused it
    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "raster"\n')
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "w").mkdir()
    os.symlink(tmp_path / "elsewhere", tmp_path / "w" / "build")
    with chdir(tmp_path / "w"):
        for _ in range(2):  # the second run finds ./out/tiny made
            result = invoke("render", scene, "--out", "build/../out")
            assert result.exit_code == 0, result.output
    assert (tmp_path / "w" / "out" / "tiny" / "raster" / "frame_0000.exr").exists()


@pytest.mark.parametrize("root", [".", "lk/..", "./"])
def test_a_root_that_normalises_to_the_working_directory_holds_the_frames(tmp_path, root):
    # `--out lk/..` (lk a link elsewhere) and `--out .` were refused as "scene.name: 'tiny'
    # would be written outside ." (a joined path in `.` has no directory part); as with
    # `build/../out`, the root is normalised: the frames go to ./tiny/raster
    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "raster"\n')
    (tmp_path / "elsewhere" / "sub").mkdir(parents=True)
    (tmp_path / "w").mkdir()
    os.symlink(tmp_path / "elsewhere" / "sub", tmp_path / "w" / "lk")
    with chdir(tmp_path / "w"):
        result = invoke("render", scene, "--out", root)
        assert result.exit_code == 0, result.output
        dotted = write(tmp_path, "d.toml", TINY + f'\n[output]\ndir = "{root}"\n')
        assert invoke("validate", dotted).output == "ok\n"
    assert (tmp_path / "w" / "tiny" / "raster" / "frame_0000.exr").exists()
    assert files_under(tmp_path / "elsewhere") == [str(tmp_path / "elsewhere" / "sub")]


@pytest.mark.parametrize(("section", "link", "field"), [
    ('[output]\ndir = "o"\n', "o/tiny", "output.dir"),
    ('[output]\nlog = "runs.jsonl"\n', "out/tiny/raytrace/runs.jsonl", "output.log"),
])
def test_an_output_folder_problem_names_the_include_its_field_came_from(tmp_path, section,
                                                                          link, field):
    """output.dir (or output.log) from an include: a link in the output folder was refused
    naming the including scene, while a too-long output.dir named the include."""
    write(tmp_path, "out.toml", section)
    scene = write(tmp_path, "s.toml", 'include = ["out.toml"]\n' + TINY)
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / link).parent.mkdir(parents=True)
    os.symlink(tmp_path / "elsewhere", tmp_path / link)
    with chdir(tmp_path):
        line = assert_one_line(invoke("validate", scene), f"out.toml: {field}: ")
        assert assert_one_line(invoke("render", scene, "--frames", "0")) == line
    assert os.listdir(tmp_path / "elsewhere") == []


def test_resume_renders_again_a_frame_whose_file_is_not_the_one_logged(tmp_path):
    # --resume compared a frame's row with the run and kept whatever file had its name: a
    # run killed between a rename and its row, a copy of another frame, a truncated file
    scene = write(tmp_path, "s.toml", TINY.replace("height = 12\n", (
        "height = 12\n[camera.path]\nframes = 5\nkeys = [{ eye = [0.0, 1.0, 3.0], "
        "target = [0.0, 0.5, 0.0] }, { eye = [1.0, 1.0, 3.0], target = [0.0, 0.5, 0.0] }]\n"))
        + '\n[technique]\nname = "raytrace"\n')
    folder = tmp_path / "o" / "tiny" / "raytrace"
    other = tmp_path / "other" / "tiny" / "raytrace"
    with chdir(tmp_path):
        assert invoke("render", scene, "--out", "o").exit_code == 0
        assert invoke("render", scene, "--out", "other", "--frames", "3",
                      "--set", "technique.max_depth=3").exit_code == 0
        before = {n: (folder / n).read_bytes() for n in os.listdir(folder)
                  if n.endswith(".exr")}
        (folder / "frame_0001.exr").write_bytes(before["frame_0004.exr"])  # another frame
        data = before["frame_0002.exr"]
        (folder / "frame_0002.exr").write_bytes(data[: len(data) // 2])  # truncated
        (folder / "frame_0003.exr").write_bytes((other / "frame_0003.exr").read_bytes())
        result = invoke("render", scene, "--out", "o", "--resume")
        assert result.exit_code == 0, result.output
        assert "wrote 3 frame(s)" in result.output and "2 skipped" in result.output
    for name, data in before.items():  # each file is its frame again
        assert (folder / name).read_bytes() == data, name


def test_a_log_with_another_hard_link_is_refused(tmp_path):
    # the rows were appended to the other name too, maybe outside the output folder
    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "raster"\n')
    folder = tmp_path / "o" / "tiny" / "raster"
    folder.mkdir(parents=True)
    victim = tmp_path / "victim.txt"
    victim.write_text("one line\n")
    os.link(victim, folder / "timings.jsonl")
    with chdir(tmp_path):
        line = assert_one_line(invoke("render", scene, "--out", "o"), "output.log",
                               "timings.jsonl", "other hard links")
        assert assert_one_line(invoke("validate", write(
            tmp_path, "v.toml", TINY + '\n[technique]\nname = "raster"\n'
            '[output]\ndir = "o"\n'))).endswith(line.partition(": ")[2])
    assert victim.read_text() == "one line\n"
    assert sorted(os.listdir(folder)) == ["timings.jsonl"]


def test_validate_refuses_a_folder_of_other_overrides_frames_as_render_does(tmp_path):
    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "raster"\n')
    with chdir(tmp_path):
        assert invoke("render", scene, "--set", "camera.width=8").exit_code == 0
        line = assert_one_line(invoke("render", scene), "holds frames rendered with other "
                               "overrides (camera.width=8)")
        assert assert_one_line(invoke("validate", scene)) == line


@contextlib.contextmanager
def read_only_view(folder):
    """`folder` seen through a read-only bind mount (root ignores permission bits: a mount
    is what refuses it a write), unmounted afterwards."""
    view = folder.parent / f"{folder.name}-ro"
    view.mkdir()
    done = subprocess.run(["mount", "--bind", str(folder), str(view)], capture_output=True)
    if done.returncode != 0:
        pytest.skip("cannot bind-mount here (not root)")
    try:
        if subprocess.run(["mount", "-o", "remount,ro,bind", str(view)],
                          capture_output=True).returncode != 0:
            pytest.skip("cannot remount read-only here")
        yield view
    finally:
        subprocess.run(["umount", "-l", str(view)], check=False)


@pytest.mark.parametrize("resume", [False, True])
def test_a_read_only_frame_folder_is_refused_in_one_line(tmp_path, resume):
    # held now that render probes its folder once it holds the lock: clearing a killed
    # run's probe there meets EROFS even where no file is (a first version of that probe
    # ended `render --resume` into a finished read-only folder in an "[Errno 30]" line)
    scene = write(tmp_path, "s.toml", TINY + '\n[technique]\nname = "raster"\n')
    with chdir(tmp_path):
        assert invoke("render", scene, "--out", tmp_path / "o").exit_code == 0
        with read_only_view(tmp_path / "o") as view:
            before = files_under(view)
            args = ("--out", view, *(("--resume",) if resume else ()))
            line = assert_one_line(invoke("render", scene, *args), "--out: cannot write to",
                                   "tiny/raster': Read-only file system")
            assert assert_one_line(invoke("validate", scene, *args)) == line
            assert files_under(view) == before
