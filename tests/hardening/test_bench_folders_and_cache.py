"""Links and non-files in the bench's own folders, `cache clear` failures, and a summary
that cannot be written: refused up front in one line (exit 2), or one line exit 1."""

from __future__ import annotations

import errno
import os
import shutil

import pytest

from .common import TINY, assert_one_line, chdir, files_under, invoke, write

BENCH = ('[bench]\nname = "b"\nout = "bout"\nframes = "0:1"\nplots = false\n'
         '[[runs]]\nscenes = ["s.toml"]\ntechniques = ["raytrace"]\n')


@pytest.fixture(scope="module")
def benched(tmp_path_factory):
    """A bench run once: its folder, copied by each test."""
    root = tmp_path_factory.mktemp("bench")
    write(root, "s.toml", TINY)
    bench = write(root, "b0.toml", BENCH)
    with chdir(root):
        result = invoke("bench", bench)
    assert result.exit_code == 0, result.output
    return root


def _copy(benched, tmp_path):
    work = tmp_path / "w"
    shutil.copytree(benched, work, symlinks=True)
    (work / "elsewhere").mkdir()
    return work


def _only_sub(folder, name):
    (entry,) = os.listdir(folder / name)
    return entry


@pytest.mark.parametrize("sub", ["references", "runs", "cache", "references/<id>",
                                 "runs/<id>"])
def test_bench_refuses_linked_subfolders(benched, tmp_path, sub):
    work = _copy(benched, tmp_path)
    bout = work / "bout"
    if "<id>" in sub:
        sub = sub.replace("<id>", _only_sub(bout, sub.split("/")[0]))
    target = bout / sub
    if target.exists():
        shutil.rmtree(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    target.symlink_to(os.path.relpath(work / "elsewhere", target.parent))
    before = files_under(bout)
    with chdir(work):
        assert_one_line(invoke("validate", "b0.toml"), "b0.toml", sub)
        assert_one_line(invoke("bench", "b0.toml"), "b0.toml", sub)
        assert_one_line(invoke("bench", "b0.toml", "--resume"), "b0.toml", sub)
    assert os.listdir(work / "elsewhere") == []
    assert files_under(bout) == before


@pytest.mark.parametrize("name", ["results.jsonl", "results.csv", "report.md"])
def test_bench_refuses_linked_result_files(benched, tmp_path, name):
    work = _copy(benched, tmp_path)
    victim = work / "elsewhere" / "victim"
    victim.write_text("keep\n")
    path = work / "bout" / name
    path.unlink()
    path.symlink_to(victim)
    with chdir(work):
        assert_one_line(invoke("validate", "b0.toml"), name)
        assert_one_line(invoke("bench", "b0.toml"), name)
    assert victim.read_text() == "keep\n"
    assert path.is_symlink()


def test_bench_refuses_a_hard_linked_results_file(benched, tmp_path):
    """results.jsonl with another name: `bench --resume` rendered the pending run, then
    failed to append its row (exit 1); refused up front now, exit 2, nothing written."""
    work = _copy(benched, tmp_path)
    rows = work / "bout" / "results.jsonl"
    rows.write_text("")  # the run is pending again
    os.link(rows, work / "elsewhere" / "other-name")
    before = files_under(work / "bout")
    with chdir(work):
        line = assert_one_line(invoke("validate", "b0.toml"), "b0.toml: bench.out:",
                               "results.jsonl' has other hard links")
        assert assert_one_line(invoke("bench", "b0.toml", "--resume")) == line
        assert assert_one_line(invoke("bench", "b0.toml")) == line
    assert files_under(work / "bout") == before
    assert rows.read_text() == "" and (work / "elsewhere" / "other-name").read_text() == ""


@pytest.mark.parametrize("where", ["tiny", "tiny/raytrace", "tiny/raytrace/timings.jsonl",
                                   "tiny/raytrace/frame_0000.exr"])
def test_bench_refuses_links_in_a_reference_folder(benched, tmp_path, where):
    """A reference is rendered again in place: a link in its folder was refused by that
    render, naming `--out` (which the bench was not given), after results.jsonl had been
    deleted; validate passed it."""
    work = _copy(benched, tmp_path)
    ref = work / "bout" / "references" / _only_sub(work / "bout", "references")
    victim = work / "elsewhere" / "victim"
    victim.write_text("keep\n")
    target = ref / where
    if target.is_dir():
        shutil.rmtree(target)
    else:
        target.unlink()
    target.symlink_to(victim if target.suffix else work / "elsewhere")
    before = files_under(work / "bout")
    with chdir(work):
        line = assert_one_line(invoke("validate", "b0.toml"), "b0.toml: bench.out:", where)
        assert assert_one_line(invoke("bench", "b0.toml")) == line
    assert "--out" not in line
    assert files_under(work / "bout") == before
    assert os.listdir(work / "elsewhere") == ["victim"] and victim.read_text() == "keep\n"


def test_validate_refuses_a_linked_lock_as_bench_does(benched, tmp_path):
    work = _copy(benched, tmp_path)
    lock = work / "bout" / ".reflect.lock"
    lock.unlink()
    lock.symlink_to(work / "elsewhere" / "made")
    with chdir(work):
        line = assert_one_line(invoke("validate", "b0.toml"), "b0.toml: bench.out:",
                               ".reflect.lock' is a symbolic link")
        assert assert_one_line(invoke("bench", "b0.toml")) == line
    assert os.listdir(work / "elsewhere") == []


MAP = "dprm-0123456789abcdef0123456789abcdef.exr"


def test_cache_clear_skips_a_directory_named_like_a_map(tmp_path):
    cache = tmp_path / "cc3"
    (cache / MAP).mkdir(parents=True)
    (cache / MAP.replace("dprm", "envm")).write_bytes(b"x")
    result = invoke("cache", "clear", "--cache", cache)
    assert result.exit_code == 0, result.output
    assert "removed 1 map(s)" in result.output
    assert (cache / MAP).is_dir()


def test_cache_clear_skips_a_link_named_like_a_map(tmp_path):
    cache = tmp_path / "cc"
    cache.mkdir()
    victim = tmp_path / "victim.exr"
    victim.write_bytes(b"x")
    (cache / MAP).symlink_to(victim)
    result = invoke("cache", "clear", "--cache", cache)
    assert result.exit_code == 0, result.output
    assert "removed 0 map(s)" in result.output
    assert victim.exists()


def test_cache_clear_read_only_is_one_line(tmp_path, monkeypatch):
    cache = tmp_path / "cc"
    cache.mkdir()
    (cache / MAP).write_bytes(b"x")

    def refuse(path, *a, **k):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))

    monkeypatch.setattr(os, "unlink", refuse)
    result = invoke("cache", "clear", "--cache", cache)
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 1, (result.output, result.exception)
    assert len(lines) == 1 and "Traceback" not in result.output
    assert MAP in lines[0] and "Read-only file system" in lines[0]


def test_cache_clear_missing_scene(tmp_path):
    with chdir(tmp_path):
        assert_one_line(invoke("cache", "clear", "nonexist.toml"), "nonexist.toml",
                        "file not found")


SCENE = TINY.replace("height = 12\n", "height = 12\n[camera.path]\nframes = 6\n"
                     "keys = [{ eye = [0.0, 1.0, 3.0], target = [0.0, 0.5, 0.0] },\n"
                     "        { eye = [1.0, 1.0, 3.0], target = [0.0, 0.5, 0.0] }]\n"
                     ) + '\n[technique]\nname = "raster"\n'


@pytest.mark.parametrize("name", ["timings-summary.json", "LOG", "frame_0001.exr",
                                  "frame_0002.png"])
def test_render_refuses_a_directory_at_a_name_it_writes(tmp_path, name):
    scene = write(tmp_path, "base.toml", SCENE)
    with chdir(tmp_path):
        from reflectcli.api import open_scene

        opened = open_scene("base.toml")
        folder = tmp_path / "out" / opened.name / opened.technique_name
        log = opened.config.output.log
        name = log if name == "LOG" else name
        (folder / name).mkdir(parents=True)
        assert_one_line(invoke("validate", scene), name)
        assert_one_line(invoke("render", scene, "--frames", "0:3", "--preview"), name)
        assert sorted(os.listdir(folder)) == [name]
        # outside the range rendered: no matter
        if name.startswith("frame_"):
            result = invoke("render", scene, "--frames", "3:4")
            assert result.exit_code == 0, result.output


def test_summary_write_failure_is_one_line(tmp_path, monkeypatch):
    from reflectcli.output import summary

    scene = write(tmp_path, "base.toml", SCENE)

    def fail(path, rows):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), path)

    monkeypatch.setattr(summary, "write_summary", fail)
    import reflectcli.api as api

    monkeypatch.setattr(api, "write_summary", fail)
    with chdir(tmp_path):
        result = invoke("render", scene, "--frames", "0:3")
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 1, (result.output, result.exception)
    assert "Traceback" not in result.output
    assert any("timings-summary.json" in line and "No space left on device" in line
               for line in lines), lines
