"""A folder of precomputed maps keyed by a hash of everything that determines them.

One EXR per map, named <kind>-<key>.exr, written atomically (its tail read back before the
rename: a full disk loses it with every call reporting success, output/exr._whole; a failed
store is one line naming the map, exit 1). A file that cannot be read (a truncated one
among them), or whose parts or recorded key do not match, is reported in one line, deleted
and recaptured: a damaged cache never stops a render. Its headers are checked against the
map looked up (MapShape) before any pixel is read: a file at a map's name whose header
claims more parts, texels or channels than that map has would otherwise allocate what it
claims.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import re
import stat
from collections.abc import Callable
from typing import NamedTuple

from ..output.exr import read_exr_parts, size_problem, write_exr_parts
from ..output.failures import reason, write_failure
from ..output.paths import remove_stale_temps

log = logging.getLogger("reflect")

KEY_ATTRIBUTE = "reflect:cache_key"
MAP_NAME = re.compile(r"^[a-z]+-[0-9a-f]{32}\.exr$")  # what path() names
# a map's temporary file while it is written (output/atomic.py): nothing else is cleared
MAP_TEMP = re.compile(r"^\.[a-z]+-[0-9a-f]{32}\.tmp(?P<pid>[0-9]{1,10})-[0-9]{1,20}\.exr$")


class RemoveFailed(OSError):
    """`<file>: cannot remove (<reason>)`: `cache clear` stops at it, in one line."""

    def __init__(self, path: str, reason: str) -> None:
        super().__init__(f"{path}: cannot remove ({reason})")
        self.path, self.reason = path, reason


class MapShape(NamedTuple):
    """What a stored map is: `parts` parts of `side` x `side` texels of `channels` channels."""

    parts: int
    side: int
    channels: int

    def problem(self, index: int, spec) -> str | None:
        """Why part `index`'s header claims more than this map holds, or None (read_exr_parts'
        `fits`): a part within the bounds is read, and `valid` checks its exact shape."""
        if index >= self.parts:
            return f"more than the map's {self.parts} part(s)"
        if spec.deep:
            return "deep (per-pixel samples), which no map is"
        return size_problem(spec, self.side, self.side * self.side, self.channels)


class Cleared(NamedTuple):
    maps: int
    temps: int  # temporary files of killed captures


def cache_key(**parts) -> str:
    """sha256 over a canonical JSON of the given values (numbers, strings, lists, dicts)."""
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=_plain).encode()).hexdigest()


def _plain(value):
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError(f"cannot hash {type(value).__name__}")


class MapCache:
    """Maps on disk under `root`; with root None, nothing is kept (every map is captured)."""

    def __init__(self, root: str | None) -> None:
        self.root = root

    def path(self, kind: str, key: str) -> str | None:
        return None if self.root is None else os.path.join(self.root, f"{kind}-{key[:32]}.exr")

    def load(self, kind: str, key: str, shape: MapShape, valid: Callable[[list], bool]):
        """The stored parts for (kind, key), or None if absent or damaged (then deleted).
        `shape` bounds the headers before any pixel is read; `valid` checks the parts read."""
        path = self.path(kind, key)
        if path is None or not os.path.lexists(path):
            return None
        try:
            if not stat.S_ISREG(os.stat(path).st_mode):
                # a named pipe blocked OpenImageIO's open for good (deaf to SIGTERM)
                raise OSError("not a regular file")
            parts = read_exr_parts(path, shape.problem)
        except OSError as e:
            reason = str(e).splitlines()[0]
            parts = None
        else:
            reason = "its content does not match its key"
            if (not parts or parts[0][2].get(KEY_ATTRIBUTE) != key or not finite(parts)
                    or not valid(parts)):
                parts = None
        if parts is None:
            log.warning("cache: %s is damaged (%s); recapturing", path, reason)
            with contextlib.suppress(OSError):
                os.unlink(path)
        return parts

    def store(self, kind: str, key: str, parts, attributes: dict[str, str],
              part_attributes: list[dict[str, str]] | None = None) -> str | None:
        path = self.path(kind, key)
        if path is None:
            return None
        try:
            os.makedirs(self.root, exist_ok=True)
            remove_stale_temps(self.root, MAP_TEMP)
            write_exr_parts(path, parts, {**attributes, KEY_ATTRIBUTE: key}, part_attributes)
        except FileNotFoundError:  # the temp file vanished mid-write: captured, not stored
            log.warning("cache: %s could not be stored (its temporary file vanished)", path)
            return None
        except OSError as e:
            raise write_failure(e, path) from None
        return path

    def clear(self) -> Cleared:
        """Delete reflect's own map files in the folder (<kind>-<32 hex digits>.exr, and
        temporary files of killed captures), nothing else; how many of each."""
        if self.root is None or not os.path.isdir(self.root):
            return Cleared(0, 0)
        temps = len(remove_stale_temps(self.root, MAP_TEMP))
        removed = 0
        try:
            entries = list(os.scandir(self.root))
        except OSError as e:
            raise RemoveFailed(self.root, reason(e, self.root)) from None
        for entry in entries:
            # only regular files are maps: a folder or a link named like one is not ours
            if not MAP_NAME.match(entry.name) or not entry.is_file(follow_symlinks=False):
                continue
            try:
                os.unlink(entry.path)
            except FileNotFoundError:
                continue
            except OSError as e:  # a read-only folder: one line naming the map, exit 1
                raise RemoveFailed(entry.path, reason(e, entry.path)) from None
            removed += 1
        return Cleared(removed, temps)


def finite(parts) -> bool:
    """Every texel a number: colors finite, depths not NaN (+inf marks 'nothing seen')."""
    import numpy as np

    for _, channels, _ in parts:
        for name, values in channels.items():
            bad = np.isnan(values) if name == "Z" else ~np.isfinite(values)
            if bad.any():
                return False
    return True


def default_cache_dir(scene_path: str) -> str:
    """`.reflect-cache/` beside the scene file."""
    return os.path.join(os.path.dirname(os.path.abspath(scene_path)), ".reflect-cache")
