"""`reflect compare`: every metric printed, --metrics chooses, warnings for unlike inputs."""

from __future__ import annotations

import numpy as np
from click.testing import CliRunner

from reflectcli.cli import cli
from reflectcli.output.exr import write_exr
from reflectcli.output.png import write_png


def _exr(path, rgb, scene="s", frame="0"):
    channels = {"R": rgb[..., 0], "G": rgb[..., 1], "B": rgb[..., 2],
                "mirror": (np.arange(rgb.shape[1])[None, :] < 8).repeat(rgb.shape[0], 0)
                .astype(np.float32)}
    write_exr(str(path), channels, {"reflect:scene": scene, "reflect:frame": frame})
    return str(path)


def test_compare_prints_every_metric_and_chooses(tmp_path):
    rng = np.random.default_rng(0)
    ref = rng.random((24, 32, 3)).astype(np.float32)
    a = _exr(tmp_path / "a.exr", ref)
    b = _exr(tmp_path / "b.exr", np.clip(ref + 0.05, 0, 1))
    r = CliRunner().invoke(cli, ["compare", a, b, "--mask-channel", "mirror"])
    assert r.exit_code == 0, r.output
    assert "over all 768 pixels" in r.output and "over 192 pixels where mirror > 0" in r.output
    for name in ("psnr", "rmse", "max_error", "frac_off", "relmse", "p50", "p95", "p99",
                 "flip", "flip_ldr", "ssim"):
        assert r.output.count(f"\n{name} ") + r.output.startswith(name) == 2, name
    assert "warning" not in r.output
    r = CliRunner().invoke(cli, ["compare", a, b, "--metrics", "ssim,psnr"])
    assert r.exit_code == 0
    lines = r.output.strip().splitlines()
    assert [ln.split()[0] for ln in lines[1:]] == ["ssim", "psnr"]
    r = CliRunner().invoke(cli, ["compare", a, b, "--metrics", "psnr,bogus"])
    assert r.exit_code == 2 and "bogus" in r.output and "Traceback" not in r.output


def test_compare_warns_about_unlike_inputs(tmp_path):
    ref = np.full((16, 16, 3), 0.25, np.float32)
    a = _exr(tmp_path / "a.exr", ref, scene="one", frame="0")
    b = _exr(tmp_path / "b.exr", ref, scene="two", frame="3")
    r = CliRunner().invoke(cli, ["compare", a, b])
    assert r.exit_code == 0
    assert "warning: scenes differ" in r.output and "warning: frames differ" in r.output
    assert "psnr      inf dB" in r.output  # warned, still scored
    png = str(tmp_path / "a.png")
    write_png(png, ref)
    r = CliRunner().invoke(cli, ["compare", png, a, "--metrics", "psnr"])
    assert r.exit_code == 0 and "sRGB-encoded" in r.output and "linear" in r.output
    r = CliRunner().invoke(cli, ["compare", png, png, "--metrics", "psnr,flip_ldr"])
    assert r.exit_code == 0 and "warning" not in r.output and "flip_ldr  0.000000" in r.output
