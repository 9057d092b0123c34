"""The raster techniques' scratch arrays are kept across frames: the primary pass's
triangle ids (`RasterWorkspace(ids=True)`; envmap's and distmap's barycentrics too),
rerender's per-level stencils, dprm's stencil and surface reconstruction
(`maps/surface.py`), distmap's step counts, virtual's reflector stencils and the screen
arrays of its dropped views (`ViewCache`), besides the rasterizer scratch kept before (ssr's
and ppr's: test_screenspace_reuse.py). What an earlier frame left in them never reaches a
frame: before each frame every kept array is filled with garbage (reuse_util.poison_all:
NaN, True, in-range wrong integers), and the frames are held to frames of a scene opened
anew (every array fresh, as a first frame has them), channel for channel and in their
stats. The frame's own arrays lie in no kept one."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import open_scene
from reuse_util import assert_frame_not_kept, assert_same_frame, kept_arrays, poison_all

SMALL = ("camera.width=96", "camera.height=72")
PRIMARY = {"tri", "own_tri", "own_key"}  # the primary pass's (ids kept; depth fresh)
PASS = {"tri", "depth", "own_tri", "own_key"}  # a pass's outputs and scratch
SURFACE = {"surface_triangle", "surface_b1", "surface_b2", "surface_depth", "surface_hit",
           "surface_ok", "surface_rgb", "surface_ids"}
VIEW = {"view_owner", "view_q", "view_r"} | PASS


def _frames_through_poison(scene: str, technique: str, overrides: tuple, frames: tuple,
                           kept_of, forget: bool = False) -> set[str]:
    """Renders `frames` of `scene` with every kept array poisoned before each (`kept_of`
    (opened, state) -> (workspaces, other kept arrays)); each frame equal to the same frame
    of a scene opened anew. `forget`: the per-view caches dropped before each frame (as the
    bench's repeats do: a new view each frame). The names of the workspace arrays poisoned
    (their union over the frames)."""
    kept = open_scene(scene, technique, (*SMALL, *overrides))
    state = kept.prepare()
    kept.render_frame(30 if len(frames) > 1 else frames[0])  # the arrays made
    fresh_frames = {}
    names = set()
    for frame in frames:
        if forget:
            kept.technique.forget_view(state)
        workspaces, extra = kept_of(kept, state)
        names |= poison_all(workspaces, kept.scene.n_objects, extra)
        got = kept.render_frame(frame)
        if frame not in fresh_frames:
            fresh_frames[frame] = open_scene(scene, technique,
                                             (*SMALL, *overrides)).render_frame(frame)
        assert_same_frame(got, fresh_frames[frame])
        workspaces, extra = kept_of(kept, state)
        assert_frame_not_kept(got, [*kept_arrays(workspaces).values(), *extra])
    return names


def _rerender_kept(opened, state):
    tech = opened.technique
    return ([tech._primary_ws, tech._pass_ws],
            [a for arrays in tech._levels.values() for a in arrays])


@pytest.mark.parametrize(("scene", "overrides", "frames"), [
    ("teapot-box", (), (40, 0, 20)),  # the camera moves: the mirror's pixels differ
    ("teapot-box", ("technique.max_depth=2",), (40, 0, 20)),
    ("hall-of-mirrors", ("technique.max_depth=3",), (0, 0)),  # facing mirrors: 3 levels
])
def test_rerender_frames_through_poisoned_kept_arrays_equal_fresh_ones(scene, overrides,
                                                                       frames):
    names = _frames_through_poison(scene, "rerender", overrides, frames, _rerender_kept)
    assert names >= PRIMARY | PASS


DPRM_SMALL = ("technique.maps.count=4", "technique.maps.resolution=64")


def _dprm_kept(opened, state):
    return ([state.buffers_raster, state.buffers.workspace],
            list(state.buffers.payloads.values()))


@pytest.mark.parametrize(("overrides", "expected"), [
    ((), PRIMARY | SURFACE | {"stencil"}),
    (('technique.reconstruct="color"',), PRIMARY | {"stencil"}),
    (("technique.fill.splat=3",), PRIMARY | SURFACE | {"stencil"}),
])
def test_dprm_frames_through_poisoned_kept_arrays_equal_fresh_ones(overrides, expected):
    names = _frames_through_poison("teapot-box", "dprm", (*DPRM_SMALL, *overrides),
                                   (40, 0, 20), _dprm_kept)
    assert names >= expected


def _virtual_kept(opened, state):
    views = state.views
    return ([state.primary_raster, state.virtual_raster, *views.spare,
             *(view.workspace for view in views.entries.values())], [])


@pytest.mark.parametrize(("scene", "overrides", "frames", "expected"), [
    # a planar mirror (one stencil for the reflector), the camera moving
    ("teapot-box", (), (40, 0, 20), {"primary_tri", "reflector_stencil"}),
    # a mesh reflector of one part (its part's stencil) and its view
    ("concave-mirror", (), (0, 0), {"primary_tri", "explosion_stencil_0"} | VIEW),
    # mesh reflectors of several parts: drawn together, and one pass (and stencil) a part
    ("mask", (), (0, 0), {"primary_tri"} | VIEW),
    ("mask", ('technique.reflector_test="clip_planes"',), (0, 0),
     {"primary_tri", "explosion_stencil_0", "explosion_stencil_1"} | VIEW),
])
def test_virtual_frames_through_poisoned_kept_arrays_equal_fresh_ones(scene, overrides,
                                                                      frames, expected):
    """The views are dropped before each frame (forget_view, as the bench's repeats do):
    the next frame's view is made in a dropped one's poisoned workspace."""
    names = _frames_through_poison(scene, "virtual", overrides, frames, _virtual_kept,
                                   forget=True)
    assert names >= expected


def test_a_new_view_reuses_a_dropped_views_arrays():
    """A view dropped by forget_view hands its workspace to the next view of the
    reflector: the new view's item buffer, depth and grid lie in the old one's memory."""
    opened = open_scene("concave-mirror", "virtual", SMALL)
    state = opened.prepare()
    opened.render_frame(0)
    (old,) = state.views.entries.values()
    opened.technique.forget_view(state)
    assert not state.views.entries and state.views.spare == [old.workspace]
    opened.render_frame(0)
    (new,) = state.views.entries.values()
    assert new is not old and not state.views.spare
    assert new.workspace is old.workspace
    for a, b in ((new.depth, old.depth), (new.grid[1], old.grid[1]),
                 (new.parts[0].triangle, old.parts[0].triangle)):
        assert np.shares_memory(a, b)


def _raster_kept(opened, state):
    return [opened.technique._primary_ws], []


def _maps_kept(opened, state):
    return [state.primary], []


@pytest.mark.parametrize(("technique", "overrides", "kept_of", "expected"), [
    ("raster", (), _raster_kept, PRIMARY),
    # barycentrics recovered for the lookups and the search (RasterBuffers.b1, b2)
    ("envmap", ("technique.resolution=32",), _maps_kept, PRIMARY | {"b1", "b2"}),
    ("distmap", ("technique.resolution=32",), _maps_kept,
     PRIMARY | {"b1", "b2", "steps_taken"}),
])
def test_primary_pass_frames_through_poisoned_kept_arrays_equal_fresh_ones(
        technique, overrides, kept_of, expected):
    """raster's, envmap's and distmap's primary pass keeps its triangle ids (and
    barycentrics); distmap its search's step counts."""
    names = _frames_through_poison("teapot-box", technique, overrides, (40, 0, 20), kept_of)
    assert names >= expected
