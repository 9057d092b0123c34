"""EXR frames: exact float round trip, attributes, determinism, atomic writes."""

from __future__ import annotations

import os

import numpy as np
import OpenImageIO as oiio
import pytest

from reflectcli.output import exr as exr_module
from reflectcli.output.atomic import atomic_path
from reflectcli.output.exr import FIXED_DATETIME, read_exr, write_exr

H, W = 5, 7  # not square, so a transposed read would show


def channels(seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    rgb = rng.standard_normal((3, H, W)).astype(np.float32) * 10.0
    rgb[0, 0, 0] = np.float32(1e-40)  # a denormal
    rgb[1, 0, 0] = np.float32(3.4e38)
    rgb[2, 0, 0] = np.float32(1.0 + 2.0**-23)  # needs full float precision, not half
    depth = rng.uniform(0.01, 100.0, (H, W)).astype(np.float32)
    depth[1, 2] = depth[4, 6] = np.inf  # background
    alpha = np.isfinite(depth).astype(np.float32)
    mirror = np.zeros((H, W), np.float32)
    mirror[2:4, 1:3] = 1.0
    holes = rng.uniform(0, 1, (H, W)).astype(np.float32)
    return {
        "R": rgb[0],
        "G": rgb[1],
        "B": rgb[2],
        "A": alpha,
        "Z": depth,
        "mirror": mirror,
        "holes": holes,
    }


ATTRS = {
    "reflect:technique": "raytrace",
    "reflect:parameters": '{"name":"raytrace","max_depth":4,"samples":1}',
    "reflect:scene_hash": "ab" * 32,
    "reflect:frame": "3",
}


def test_round_trip_is_exact(tmp_path):
    path = tmp_path / "frame.exr"
    data = channels()
    write_exr(str(path), data, ATTRS)
    back, _ = read_exr(str(path))
    assert set(back) == set(data)
    for name, values in data.items():
        assert back[name].dtype == np.float32
        assert back[name].shape == (H, W)
        np.testing.assert_array_equal(back[name], values, err_msg=name)
    assert np.isposinf(back["Z"][1, 2]) and np.isposinf(back["Z"][4, 6])
    assert np.isfinite(back["Z"]).sum() == H * W - 2


def test_channels_are_stored_as_float_not_half(tmp_path):
    path = tmp_path / "frame.exr"
    write_exr(str(path), channels(), ATTRS)
    inp = oiio.ImageInput.open(str(path))
    try:
        spec = inp.spec()
        assert (
            list(spec.channelformats or [spec.format] * spec.nchannels)
            == [oiio.TypeDesc(oiio.FLOAT)] * spec.nchannels
        )
    finally:
        inp.close()


def test_attributes_are_kept(tmp_path):
    path = tmp_path / "frame.exr"
    write_exr(str(path), channels(), ATTRS)
    _, attrs = read_exr(str(path))
    for key, value in ATTRS.items():
        assert attrs[key] == value
    assert attrs["DateTime"] == FIXED_DATETIME


def test_non_string_attributes_are_written_as_strings(tmp_path):
    path = tmp_path / "frame.exr"
    write_exr(str(path), channels(), {"reflect:frame": 12})
    _, attrs = read_exr(str(path))
    assert attrs["reflect:frame"] == "12"


def test_same_input_gives_byte_identical_files(tmp_path):
    a, b = tmp_path / "a.exr", tmp_path / "b.exr"
    write_exr(str(a), channels(), ATTRS)
    write_exr(str(b), channels(), ATTRS)
    assert a.read_bytes() == b.read_bytes()
    write_exr(str(b), channels(seed=1), ATTRS)
    assert a.read_bytes() != b.read_bytes()  # the comparison above can fail


def test_write_leaves_no_temporary_file(tmp_path):
    write_exr(str(tmp_path / "frame.exr"), channels(), ATTRS)
    assert sorted(os.listdir(tmp_path)) == ["frame.exr"]


class _FailingOutput:
    """Wraps a real ImageOutput: opens (so the temporary file exists on disk), then fails."""

    def __init__(self, real, mode: str, seen: list):
        self.real, self.mode, self.seen = real, mode, seen

    def open(self, path, spec):
        self.path = path
        return self.real.open(path, spec)

    def write_image(self, data):
        self.seen.append(sorted(os.listdir(os.path.dirname(self.path))))
        if self.mode == "raise":
            raise RuntimeError("disk on fire")
        return False

    def close(self):
        return self.real.close()


@pytest.fixture
def failing_oiio(monkeypatch):
    seen: list = []

    def install(mode: str):
        real_output = oiio.ImageOutput

        class Factory:
            @staticmethod
            def create(path):
                return _FailingOutput(real_output.create(path), mode, seen)

        monkeypatch.setattr(oiio, "ImageOutput", Factory)
        return seen

    return install


@pytest.mark.parametrize("mode", ["raise", "false"])
def test_failed_write_leaves_no_file(tmp_path, failing_oiio, mode):
    seen = failing_oiio(mode)
    path = tmp_path / "frame.exr"
    with pytest.raises(RuntimeError if mode == "raise" else OSError):
        write_exr(str(path), channels(), ATTRS)
    # the failure came mid-write: a temporary file existed beside the target
    assert len(seen) == 1 and len(seen[0]) == 1 and seen[0][0].startswith(".")
    assert os.listdir(tmp_path) == []


def test_failed_write_keeps_the_previous_file(tmp_path, failing_oiio):
    path = tmp_path / "frame.exr"
    write_exr(str(path), channels(seed=5), ATTRS)
    before = path.read_bytes()
    failing_oiio("raise")
    with pytest.raises(RuntimeError):
        write_exr(str(path), channels(seed=6), ATTRS)
    assert path.read_bytes() == before
    assert os.listdir(tmp_path) == ["frame.exr"]


def test_unwritable_target_raises_oserror(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(OSError):
        write_exr(str(blocker / "frame.exr"), channels(), ATTRS)


def test_atomic_path_cleans_up_on_interrupt(tmp_path):
    target = tmp_path / "x.bin"
    with pytest.raises(KeyboardInterrupt), atomic_path(str(target)) as tmp:
        assert os.path.dirname(tmp) == str(tmp_path)
        assert os.path.basename(tmp).startswith(".") and tmp.endswith(".bin")
        with open(tmp, "wb") as f:
            f.write(b"partial")
        raise KeyboardInterrupt
    assert os.listdir(tmp_path) == []


def test_atomic_path_replaces_on_success(tmp_path):
    target = tmp_path / "x.bin"
    target.write_bytes(b"old")
    with atomic_path(str(target)) as tmp:
        with open(tmp, "wb") as f:
            f.write(b"new")
        assert target.read_bytes() == b"old"  # not replaced before the block ends
    assert target.read_bytes() == b"new"
    assert os.listdir(tmp_path) == ["x.bin"]


def test_read_missing_file_raises_oserror(tmp_path):
    with pytest.raises(OSError):
        exr_module.read_exr(str(tmp_path / "nope.exr"))
