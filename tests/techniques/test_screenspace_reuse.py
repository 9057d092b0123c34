"""ssr's and ppr's ray table (screenspace/rays.py) is kept across frames in the technique's
workspace: what an earlier frame left in it never reaches a frame. The table is first
filled with NaN and `valid` with True, so that a row or flag read without being written this
frame shows; the frames are held to the same frames made with fresh zeroed arrays (the
arrays mirror_rays makes without a workspace, as every frame had them before)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import open_scene
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
    _poisoned(kept.prepare()["rays"], 72, 96)
    masks = []
    for frame in (40, 0, 20):
        got = kept.render_frame(frame)
        fresh = open_scene("teapot-box", technique, SMALL)
        fresh.prepare()["rays"] = None  # mirror_rays' own zeroed arrays
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
