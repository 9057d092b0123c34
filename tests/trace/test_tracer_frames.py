"""Whole ray-traced frames: the same bytes for any thread count and run, and with the embreex
fallback tracing instead of the kernels."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import compiled_only, open_scene

SMALL = ("camera.width=96", "camera.height=72")
# planar mirrors and a spp of 2; curved mirrors traced as triangles; lit spheres; mirrors
# facing each other (every bounce)
CASES = [("teapot-box", ("technique.samples=2",)), ("concave-mirror", ()),
         ("four-spheres-lit", ()), ("hall-of-mirrors", ("technique.max_depth=6",))]


def frame_arrays(frame) -> list[np.ndarray]:
    return [frame.rgb, frame.depth, frame.surface, frame.mirror_mask,
            *(frame.extra[k] for k in sorted(frame.extra))]


@pytest.mark.parametrize(("scene", "extra"), CASES)
def test_frames_do_not_depend_on_the_thread_count(scene, extra):
    """Each wave's segments go to whichever thread is free; every ray writes only its own
    outputs, so frames are the same bytes with one thread or two, run after run."""
    frames = []
    for threads in (1, 2, 2):
        opened = open_scene(scene, "raytrace", (*SMALL, *extra), threads=threads)
        frames.append([frame_arrays(opened.render_frame(f)) for f in (0, 1)])
    for other in frames[1:]:
        for a, b in zip(frames[0], other, strict=True):
            for x, y in zip(a, b, strict=True):
                assert x.dtype == y.dtype and x.tobytes() == y.tobytes()


@compiled_only
@pytest.mark.parametrize(("scene", "extra"), CASES)
def test_embreex_fallback_gives_the_same_frames(scene, extra, monkeypatch):
    """Without the library file for the kernels the embreex binding traces each wave's rays
    before the wave, one wave a call, where the kernels take each segment through all its
    waves in one call: the same bytes (Embree's hits are the same to the bit either way)."""
    import reflectcli.trace.embree as embree

    want = frame_arrays(open_scene(scene, "raytrace", (*SMALL, *extra)).render_frame(0))
    monkeypatch.setattr(embree, "_embree", lambda: None)
    opened = open_scene(scene, "raytrace", (*SMALL, *extra))
    got = frame_arrays(opened.render_frame(0))
    accel = opened._state.accel
    assert accel.objects.count and not accel.objects.handle  # embreex traced them
    for x, y in zip(got, want, strict=True):
        assert x.dtype == y.dtype and x.tobytes() == y.tobytes()


@compiled_only
@pytest.mark.parametrize(("scene", "extra"), CASES)
def test_fast_embree_scenes_give_nearly_the_same_frames(scene, extra):
    """`embree = "fast"` (Mitsuba 3's scene settings, for a speed comparison like for
    like: no robust flag, high build quality) traverses another tree and works its hits
    with other rounding (music-room at full size: surfaces the same, colours within 3e-4):
    the frames agree with the robust ones within float32 rounding but for a ray now and
    then through a shared edge, and keep their bytes from run to run."""
    robust = frame_arrays(open_scene(scene, "raytrace", (*SMALL, *extra)).render_frame(0))
    runs = []
    for _ in range(2):
        opened = open_scene(scene, "raytrace", (*SMALL, *extra, "technique.embree=fast"))
        runs.append(frame_arrays(opened.render_frame(0)))
    assert opened.technique.params.embree == "fast"
    for x, y in zip(*runs, strict=True):
        assert x.tobytes() == y.tobytes()
    # (limits with room: another ISA's non-robust code may round otherwise)
    close = np.all(np.abs(runs[0][0] - robust[0]) <= 1e-3, axis=-1)
    assert close.mean() > 0.995, close.mean()
    assert (runs[0][2] == robust[2]).mean() > 0.995  # the surface under each pixel
    accel = opened._state.accel
    assert accel.objects._embree.scene_flags(accel.objects.handle) == 0  # not robust
