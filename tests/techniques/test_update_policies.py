"""Map update policies (`update`, `faces_per_frame`; reflectcli/maps/update.py) for envmap,
dprm and distmap: staleness against capture cost on moving-probe, and no effect at all on a
static scene."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import open_scene

from reflectcli.maps.update import face_capture_frames, faces_updated, map_capture_frame

SMALL = ("camera.width=120", "camera.height=90")
FRAMES = range(12)  # half the orbit: the satellite moves 15 degrees a frame
POLICIES = ("once", 8, 4, 2, "every")  # update intervals growing from right to left


def _policy(update) -> str:
    return f'technique.update="{update}"' if isinstance(update, str) else \
        f"technique.update={update}"


def _sweep(technique: str, overrides: tuple[str, ...], refs=None, size=SMALL):
    """Per policy: squared error summed over the ball's pixels against `refs` (or against
    the policy "every", if refs is None), faces captured and capture seconds, per frame."""
    runs = {}
    for update in POLICIES:
        opened = open_scene("moving-probe", technique, (_policy(update),) + size + overrides)
        frames = [opened.render_frame(f) for f in FRAMES]
        ball = opened.scene.n_objects + opened.scene.mirrors.names.index("ball")
        faces = sum(f.stats["faces_captured"] for f in frames) / len(frames)
        # recaptures after frame 0 (frame 0's capture, in precompute, is the same for all)
        seconds = sum(f.timings["capture"] for f in frames[1:]) / len(frames)
        runs[update] = (frames, ball, faces, seconds)
    refs = refs if refs is not None else runs["every"][0]
    out = {}
    for update, (frames, ball, faces, seconds) in runs.items():
        se, n = 0.0, 0
        for ours, ref in zip(frames, refs, strict=True):
            m = (ours.surface == ball) & (ref.surface == ball)
            se += float(((ours.rgb[m].astype(np.float64) - ref.rgb[m]) ** 2).sum())
            n += 3 * int(m.sum())
        out[update] = (se / max(n, 1), faces, seconds)
    return out


def test_moving_probe_staleness_against_capture_cost():
    """distmap (layers 4, near exact on the ball when fresh): the ball's error against the
    ray tracer rises with the update interval, while the capture cost per frame falls; envmap
    (whose own parallax error on the near object hides staleness against the ray tracer):
    its error against its own every-frame maps rises with the interval."""
    ref = open_scene("moving-probe", "raytrace", ("technique.max_depth=1",) + SMALL)
    refs = [ref.render_frame(f) for f in FRAMES]
    dist = _sweep("distmap", ("technique.layers=4", "technique.resolution=64"), refs)
    mse = [dist[u][0] for u in POLICIES]
    assert all(a > b for a, b in zip(mse, mse[1:], strict=False)), mse
    assert mse[0] > 3 * mse[-1], mse  # stale by up to 11 frames vs fresh: > 4.8 dB
    faces = [dist[u][1] for u in POLICIES]
    assert faces == [1.0, 2.0, 3.0, 6.0, 12.0], faces  # 2 mirrors x 6 faces per capture
    # 0, 1, 2, 5 and 11 recaptures; wall-clock time on a shared machine: coarse checks only
    seconds = [dist[u][2] for u in POLICIES]
    assert seconds[0] < 0.2 * seconds[1] and seconds[4] > 2 * seconds[1], seconds
    env = _sweep("envmap", ("technique.resolution=64",), size=("camera.width=80",
                                                               "camera.height=60"))
    stale = [env[u][0] for u in POLICIES]
    assert all(a > b for a, b in zip(stale[:-1], stale[1:-1], strict=False)), stale
    assert stale[-2] > 0.0 and stale[-1] == 0.0, stale


def test_time_sliced_faces_cost_and_staleness():
    """faces_per_frame = 1 with update every frame: one face a frame per mirror (the cost of
    update = 6 with whole cubes), each face at most 5 frames old."""
    assert [faces_updated(f, "every", 1) for f in range(8)] == [6, 1, 1, 1, 1, 1, 1, 1]
    assert face_capture_frames(7, "every", 1) == [6, 7, 2, 3, 4, 5]
    assert face_capture_frames(9, 2, 2) == [6, 6, 8, 8, 4, 4]
    assert map_capture_frame(9, 4) == 8 and map_capture_frame(9, "once") == 0
    opened = open_scene("moving-probe", "envmap", ('technique.update="every"',
                                                   "technique.faces_per_frame=1",
                                                   "technique.resolution=32",
                                                   "camera.width=64", "camera.height=48"))
    stats = [opened.render_frame(f).stats["faces_captured"] for f in range(4)]
    assert stats == [12, 2, 2, 2], stats


@pytest.mark.parametrize(("technique", "extra"), [
    ("envmap", ("technique.faces_per_frame=2",)),
    ("distmap", ("technique.faces_per_frame=3", "technique.layers=2")),
    ("dprm", ("technique.maps.resolution=64",)),
])
def test_static_scene_same_images_for_every_policy(technique, extra):
    """Nothing moves in teapot-box (only the camera): every policy renders the same pixels."""
    small = ("camera.width=80", "camera.height=60") + (
        () if technique == "dprm" else ("technique.resolution=32",))
    images = []
    for update in ("once", 2, "every"):
        opened = open_scene("teapot-box", technique, (_policy(update),) + small + extra)
        images.append([opened.render_frame(f).rgb for f in (0, 3, 5)])
    for other in images[1:]:
        for a, b in zip(images[0], other, strict=True):
            np.testing.assert_array_equal(a, b)


def test_envmap_warns_about_moving_objects_captured_once(caplog):
    with caplog.at_level("WARNING", logger="reflect"):
        open_scene("moving-probe", "envmap", ("technique.resolution=8",)).prepare()
        assert any("objects move" in r.getMessage() for r in caplog.records)
        caplog.clear()
        open_scene("moving-probe", "envmap", ("technique.resolution=8",
                                              "technique.update=4")).prepare()
        assert not any("objects move" in r.getMessage() for r in caplog.records)


def test_sphere_maps_need_whole_cubes():
    from reflectcli.errors import Problems

    with pytest.raises(Problems, match="faces_per_frame"):
        open_scene("moving-probe", "envmap", ('technique.map="sphere"',
                                              "technique.faces_per_frame=2")).prepare()
