"""ssr's and ppr's scratch arrays are kept across frames in the technique's workspaces (the
ray table of screenspace/rays.py; the march and decode outputs, the hiz pyramid, the colour
copy, ppr's scatter arrays, the primary pass's rasterizer scratch, triangle ids and
barycentrics, the envmap fallback's ids): what an earlier frame left in them never reaches
a frame. They are first filled with garbage (the table with NaN and `valid` with True; every
kept array, below, with NaN, True or in-range wrong values), so that an element read
without being written this frame shows; the frames are held to the same frames made with
fresh arrays (what every frame had before: no workspace)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import open_scene
from reuse_util import poison
from screenspace_util import primary_of

from reflectcli.raster.rasterize import RasterWorkspace
from reflectcli.screenspace.rays import RAY_COLS, TABLE, VALID, mirror_rays

SMALL = ("camera.width=96", "camera.height=72")


def _poisoned(workspace: RasterWorkspace, h: int, w: int) -> None:
    workspace.get(TABLE, (h, w, RAY_COLS), np.float32)[:] = np.nan
    workspace.get(VALID, (h, w), np.bool_)[:] = True


def _assert_same_frame(got, want) -> None:
    for name in ("rgb", "depth", "surface", "mirror_mask"):
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)
    assert sorted(got.extra) == sorted(want.extra)
    for name, values in want.extra.items():
        np.testing.assert_array_equal(got.extra[name], values, err_msg=name)
    assert got.stats == want.stats


@pytest.mark.parametrize("technique", ["ssr", "ppr"])
def test_frames_through_the_kept_table_equal_frames_with_fresh_ones(technique):
    # teapot-box's camera path: the mirror's pixels differ from frame to frame (asserted)
    kept = open_scene("teapot-box", technique, SMALL)
    _poisoned(kept.prepare()["screen"], 72, 96)
    masks = []
    for frame in (40, 0, 20):
        got = kept.render_frame(frame)
        fresh = open_scene("teapot-box", technique, SMALL)
        _fresh_arrays(fresh.prepare())  # mirror_rays' own zeroed arrays among them
        _assert_same_frame(got, fresh.render_frame(frame))
        masks.append(got.mirror_mask)
    for a, b in zip(masks, masks[1:], strict=False):
        assert (a & ~b).any()  # pixels whose rows the frame before left in the table


def test_the_kept_table_is_written_wherever_it_is_read():
    """Every pixel's `valid` and every mirror pixel's row, also where no ray starts (a near
    plane beyond part of the mirror: rows of zeros, which ppr's decode reads), equal the
    fresh arrays'; the other rows are left as they were."""
    primary, built, camera = primary_of("teapot-box", 0, SMALL)
    mirror = primary.frame.mirror_mask
    depths = primary.frame.depth[mirror]
    far_near = dataclasses.replace(camera, near=float(np.median(depths)))
    for cam in (camera, far_near):
        args = (primary.buffers, primary.frame.surface, built.n_objects, primary.triangles,
                built.mirrors, cam, 20.0)
        want_rays, want_valid = mirror_rays(*args)
        ws = RasterWorkspace()
        _poisoned(ws, 72, 96)
        rays, valid = mirror_rays(*args, ws)
        np.testing.assert_array_equal(valid, want_valid)
        np.testing.assert_array_equal(rays[mirror], want_rays[mirror])
        assert np.isnan(rays[~mirror]).all()
        if cam is far_near:
            assert (mirror & ~valid).sum() > 100  # the rows of zeros were written


def _fresh_arrays(state: dict) -> None:
    """No workspace anywhere: every scratch array fresh each frame, as before they were
    kept."""
    state["primary"] = state["screen"] = None
    state["fallback"].workspace = None


# every array a frame may keep (in the technique's and its fallback's workspaces)
SCREEN = {"mirror_rays", "mirror_rays_valid", "march_hit", "march_hx", "march_hy",
          "march_dist", "march_gap", "march_lookups", "colors"}
HIZ = {"hiz_pyramid"}
PPR = {"ppr_keys_min", "ppr_targets", "ppr_keys", "ppr_filled"}
PPR_FILL = {"ppr_keys_filled"}
PRIMARY = {"tri", "b1", "b2", "own_tri", "own_key"}
ENVMAP = {"missed_ids"}


def _poison_all(workspaces, n_objects: int) -> set[str]:
    """Every scratch array the workspaces hold (not their constants or kept answers) filled
    with garbage: NaN, True, 1 (a hit), 0 as a key (source pixel 0 at distance 0) and
    `n_objects` for other integers (the first mirror's surface id; a triangle, a pixel
    index and a coordinate that exist), in range so that a stale read shows as a wrong
    frame rather than a crash. The names poisoned."""
    names = set()
    for ws in workspaces:
        for name, a in ws._arrays.items():
            if not isinstance(a, np.ndarray) or ":" in name:
                continue
            poison(a, n_objects)
            names.add(name)
    return names


@pytest.mark.parametrize(("technique", "overrides", "expected"), [
    ("ssr", (), SCREEN | HIZ | PRIMARY | ENVMAP),
    ("ssr", ('technique.march="dda"', "technique.jitter=0.5", "technique.stride=2.0",
             'technique.fallback="none"'), SCREEN | PRIMARY),
    ("ssr", ('technique.march="linear"', 'technique.resolve="pixel"',
             'technique.fallback="rerender"'), SCREEN | PRIMARY),
    ("ppr", (), SCREEN | PPR | PPR_FILL | PRIMARY | ENVMAP),
    ("ppr", ("technique.fill=false", 'technique.resolve="pixel"'),
     SCREEN | PPR | PRIMARY | ENVMAP),
])
def test_frames_through_poisoned_kept_arrays_equal_frames_with_fresh_ones(
        technique, overrides, expected):
    """Before each frame every kept array is poisoned; the frames (teapot-box's camera
    path: the mirror's pixels move) equal frames made with fresh arrays, channel for
    channel and in their stats."""
    kept = open_scene("teapot-box", technique, (*SMALL, *overrides))
    state = kept.prepare()
    workspaces = (state["primary"], state["screen"], state["fallback"].workspace)
    fresh = open_scene("teapot-box", technique, (*SMALL, *overrides))
    _fresh_arrays(fresh.prepare())
    n_objects = state["scene"].n_objects
    kept.render_frame(30)  # the arrays made
    for frame in (40, 0, 20):
        assert _poison_all(workspaces, n_objects) >= expected
        got = kept.render_frame(frame)
        _assert_same_frame(got, fresh.render_frame(frame))
        # the Frame's own arrays are fresh: none lies in a kept array (a caller or the
        # writer may hold them while the next frame renders)
        ours = [a for ws in workspaces for a in ws._arrays.values()
                if isinstance(a, np.ndarray)]
        for a in (got.rgb, got.depth, got.surface, got.mirror_mask, *got.extra.values()):
            assert not any(np.may_share_memory(a, b) for b in ours)


def test_the_primary_pass_keeps_its_ids_and_barycentrics_but_not_its_depth():
    """A workspace made with ids=True keeps the triangle ids and the recovered
    barycentrics across passes; the depth buffer (the frame keeps it) is fresh each pass."""
    from reflectcli.raster.primary import render_primary

    opened = open_scene("teapot-box", "ssr", SMALL)
    scene = opened.prepare()["scene"]
    ws = RasterWorkspace(ids=True)
    first = render_primary(scene, 0, opened.camera(0), ws)
    first_b1 = first.buffers.b1
    second = render_primary(scene, 10, opened.camera(10), ws)
    assert second.buffers.triangle is not first.buffers.triangle
    assert np.shares_memory(second.buffers.triangle, first.buffers.triangle)
    assert np.shares_memory(second.buffers.b1, first_b1)
    assert not np.shares_memory(second.frame.depth, first.frame.depth)
    fresh = render_primary(scene, 10, opened.camera(10))
    for name in ("triangle", "b1", "b2", "depth"):
        np.testing.assert_array_equal(getattr(second.buffers, name),
                                      getattr(fresh.buffers, name), err_msg=name)
