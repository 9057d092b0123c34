"""bench --out and --set; --scheduler with nothing behind it fails in one line, its
connection bounded by a timeout; a second bench on the same output folder stops in one
line."""

from __future__ import annotations

import pytest

from reflectcli.bench import runner
from reflectcli.errors import Problems
from reflectcli.output.lock import folder_lock

from .common import TINY, assert_one_line, chdir, held_elsewhere, invoke, write

BENCH = ('[bench]\nname = "b"\nframes = "0"\nplots = false\n'
         '[[runs]]\nscenes = ["s.toml"]\ntechniques = ["raster"]\n')


def test_bench_out_and_set(tmp_path):
    write(tmp_path, "s.toml", TINY)
    bench = write(tmp_path, "b.toml", BENCH)
    with chdir(tmp_path):
        result = invoke("bench", bench, "--out", tmp_path / "elsewhere", "--set",
                        "camera.width=8")
        assert result.exit_code == 0, result.output
        rows = (tmp_path / "elsewhere" / "results.jsonl").read_text()
        assert '"camera.width=8"' in rows
        assert not (tmp_path / "out").exists()
        assert_one_line(invoke("bench", bench, "--set", "camera.widht=8"), "camera.widht",
                        "did you mean width?")


def test_scheduler_without_a_cluster_fails_fast(tmp_path):
    write(tmp_path, "s.toml", TINY)
    bench = write(tmp_path, "b.toml", BENCH)
    with chdir(tmp_path):
        result = invoke("bench", bench, "--scheduler", "tcp://127.0.0.1:9", "--out",
                        tmp_path / "o")
    assert_one_line(result, "--scheduler: no Dask scheduler answers at 'tcp://127.0.0.1:9'")
    assert not (tmp_path / "o" / "references").exists()


def test_scheduler_connection_has_a_timeout():
    """The client is asked to give up within seconds (Dask's own default waits 30 s), and
    its failure becomes the one-line problem (no timed test: a busy machine stretches any
    wall-clock bound)."""
    asked = {}

    class Unreachable:
        def __init__(self, address, timeout=None):
            asked.update(address=address, timeout=timeout)
            raise TimeoutError("Timed out trying to connect")

    with pytest.raises(Problems, match="no Dask scheduler answers at 'tcp://h:1'"):
        runner._connect(Unreachable, "tcp://h:1")
    assert asked == {"address": "tcp://h:1", "timeout": "5s"}


def test_second_bench_on_one_folder_stops(tmp_path):
    write(tmp_path, "s.toml", TINY)
    bench = write(tmp_path, "b.toml", BENCH)
    with held_elsewhere(folder_lock, tmp_path / "o"), chdir(tmp_path):
        result = invoke("bench", bench, "--out", tmp_path / "o")
    assert_one_line(result, "--out:", "is being written by another bench")



@pytest.mark.parametrize("damage", ["truncated", "garbage"])
def test_an_unreadable_run_frame_blanks_its_contact_sheet_line_with_a_warning(
        tmp_path, caplog, damage):
    # `bench --resume` keeps the rows (measured when the frame was whole) and draws the
    # contact sheet from the frames they name: a frame damaged since ended the bench as a
    # write failure (exit 1, "cannot read ...") after its results and report were written,
    # the last bench's contact sheet left in place. Now that line of the sheet is blank and
    # one warning names the file; the bench's other outputs stand (exit 0).
    pytest.importorskip("matplotlib")
    import json

    write(tmp_path, "s.toml", TINY)
    bench = write(tmp_path, "b.toml", BENCH.replace("plots = false", "plots = true"))
    out = tmp_path / "o"
    with chdir(tmp_path):
        assert invoke("bench", bench, "--out", out).exit_code == 0
        (row,) = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
        frame = tmp_path / row["images"][0]
        whole = frame.read_bytes()
        frame.write_bytes(whole[:700] if damage == "truncated" else b"garbage")
        (out / "contact-tiny.png").unlink()
        with caplog.at_level("WARNING", logger="reflect"):
            result = invoke("bench", bench, "--out", out, "--resume")
    assert result.exit_code == 0, result.output
    assert "Traceback" not in result.output
    warned = [r.getMessage() for r in caplog.records if "contact-tiny.png" in r.getMessage()]
    assert len(warned) == 1, warned
    assert f"{row['images'][0]}: unreadable (" in warned[0]
    assert f"run {row['run']}'s line left blank" in warned[0]
    assert (out / "contact-tiny.png").exists() and (out / "report.md").exists()
