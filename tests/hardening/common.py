"""Shared helpers for the hardening tests: a tiny scene and the one-line, exit-2 contract."""

from __future__ import annotations

import contextlib
import multiprocessing
import os
from pathlib import Path

from click.testing import CliRunner
from test_cli import TINY as CLI_TINY

from reflectcli.cli import cli

# test_cli's tiny scene (a ball over a floor mirror) at 16x12
TINY = CLI_TINY.replace("width = 32\nheight = 24", "width = 16\nheight = 12")
assert TINY != CLI_TINY


def invoke(*args: str):
    return CliRunner().invoke(cli, [str(a) for a in args])


def files_under(folder: Path) -> list[str]:
    return sorted(str(p) for p in folder.rglob("*")) if folder.exists() else []


def assert_one_line(result, *needles: str) -> str:
    """Exit 2, exactly one output line, no traceback; the line contains every needle."""
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 2, (result.exit_code, result.output, result.exception)
    assert len(lines) == 1, result.output
    assert "Traceback" not in result.output
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


def check_bad(scene: Path, *needles: str, extra: tuple = ()) -> str:
    """`validate` and `render` both refuse `scene` in one line, and render writes nothing."""
    out = scene.parent / "out-bad"
    line = assert_one_line(invoke("validate", scene), *needles)
    line2 = assert_one_line(invoke("render", scene, "--out", out, "--frames", "0", *extra),
                            *needles)
    assert files_under(out) == []
    assert line == line2
    return line


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text)
    return path


def chdir(path: Path):
    class _Cd:
        def __enter__(self):
            self.old = os.getcwd()
            os.chdir(path)

        def __exit__(self, *exc):
            os.chdir(self.old)

    return _Cd()


def _hold(lock, folder: str, ready, release) -> None:
    with lock(folder, "x"):
        ready.set()
        release.wait(30)


@contextlib.contextmanager
def held_elsewhere(lock, folder: Path):
    """`lock(folder, ...)` (output/lock.py) held by another process for the body, as a
    render or bench running beside this one holds it."""
    ready, release = multiprocessing.Event(), multiprocessing.Event()
    holder = multiprocessing.get_context("fork").Process(
        target=_hold, args=(lock, str(folder), ready, release))
    holder.start()
    try:
        assert ready.wait(30)
        yield
    finally:
        release.set()
        holder.join(30)
