"""SIGTERM is handled like Ctrl-C; Ctrl-C during start-up exits 130; the number of frames
reported kept is exact."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "teapot-box.toml"
COMMAND = [sys.executable, "-m", "reflectcli.cli", "render", str(SCENE), "--technique",
           "raytrace", "--set", "camera.width=64", "--set", "camera.height=48", "--threads", "1"]


def test_sigterm_mid_render_is_like_ctrl_c(tmp_path):
    folder = tmp_path / "teapot-box" / "raytrace"
    proc = subprocess.Popen([*COMMAND, "--out", str(tmp_path)], stderr=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while time.time() < deadline and not (folder.exists() and any(folder.glob("*.exr"))):
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    kept = int(re.search(r"interrupted: (\d+) completed frame\(s\) kept", err).group(1))
    exrs = sorted(folder.glob("*.exr"))
    log = (folder / "timings.jsonl").read_text().splitlines()
    assert kept == len(exrs) == len(log) >= 1
    assert not [n for n in os.listdir(folder) if n.startswith(".")]


def test_ctrl_c_during_start_up_exits_130(tmp_path):
    proc = subprocess.Popen([*COMMAND, "--out", str(tmp_path)], stderr=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    time.sleep(0.6)  # importing: before any command handler runs
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "interrupted" in err
