"""Shared helpers of the tests that hold frames rendered through kept (reused) arrays to
frames rendered with fresh ones: garbage in every kept array, and the frames compared."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from reflectcli.raster.rasterize import RasterWorkspace


def poison(a: np.ndarray, n_objects: int) -> None:
    """`a` filled with garbage in range, so that a stale read shows as a wrong frame rather
    than a crash: NaN, True, 1 (a hit), 0 as a uint64 key (source pixel 0 at distance 0)
    and `n_objects` for other integers (the first mirror's surface id; a triangle, a pixel
    index and a coordinate that exist)."""
    if a.dtype.kind == "f":
        a.fill(np.nan)
    elif a.dtype == np.bool_:
        a.fill(True)
    elif a.dtype == np.uint8:
        a.fill(1)
    elif a.dtype == np.uint64:
        a.fill(0)
    else:
        a.fill(n_objects)


def kept_arrays(workspaces: Iterable[RasterWorkspace | None]) -> dict[str, np.ndarray]:
    """The scratch arrays the workspaces hold: not their constants, kept answers or flags
    (names with a colon), nor an array given back zeroed (`RasterWorkspace.zeroed`: its
    zeros are part of what is kept). Keyed by workspace position and name."""
    arrays = {}
    for i, ws in enumerate(workspaces):
        if ws is None:
            continue
        for name, a in ws._arrays.items():
            if (isinstance(a, np.ndarray) and ":" not in name
                    and not ws._arrays.get(f"{name}:zeroed", False)):
                arrays[f"{i}:{name}"] = a
    return arrays


def poison_all(workspaces: Iterable[RasterWorkspace | None], n_objects: int,
               extra: Iterable[np.ndarray] = ()) -> set[str]:
    """Every scratch array of the workspaces (`kept_arrays`), and `extra`, poisoned; the
    workspace arrays' names."""
    arrays = kept_arrays(workspaces)
    for a in (*arrays.values(), *extra):
        poison(a, n_objects)
    return {key.split(":", 1)[1] for key in arrays}


def assert_same_frame(got, want) -> None:
    """Channel for channel and stat for stat (timings and stats in seconds aside)."""
    for name in ("rgb", "depth", "surface", "mirror_mask"):
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)
    assert sorted(got.extra) == sorted(want.extra)
    for name, values in want.extra.items():
        np.testing.assert_array_equal(got.extra[name], values, err_msg=name)

    def stats(frame) -> dict:
        return {k: v for k, v in frame.stats.items() if "seconds" not in k}

    assert stats(got) == stats(want)


def assert_frame_not_kept(frame, arrays: Iterable[np.ndarray]) -> None:
    """None of the Frame's own arrays lies in a kept one (a caller or the writer may hold
    them while the next frame renders)."""
    arrays = list(arrays)
    for a in (frame.rgb, frame.depth, frame.surface, frame.mirror_mask, *frame.extra.values()):
        assert not any(np.may_share_memory(a, b) for b in arrays)
