"""A folder of precomputed maps keyed by a hash of everything that determines them.

One EXR per map, named <kind>-<key>.exr, written atomically. A file that cannot be read, or
whose parts or recorded key do not match, is reported in one line, deleted and recaptured:
a damaged cache never stops a render.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
from collections.abc import Callable

from ..output.exr import read_exr_parts, write_exr_parts

log = logging.getLogger("reflect")

KEY_ATTRIBUTE = "reflect:cache_key"


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

    def load(self, kind: str, key: str, valid: Callable[[list], bool]):
        """The stored parts for (kind, key), or None if absent or damaged (then deleted)."""
        path = self.path(kind, key)
        if path is None or not os.path.exists(path):
            return None
        try:
            parts = read_exr_parts(path)
        except OSError as e:
            reason = str(e).splitlines()[0]
            parts = None
        else:
            reason = "its content does not match its key"
            if not parts or parts[0][2].get(KEY_ATTRIBUTE) != key or not valid(parts):
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
        os.makedirs(self.root, exist_ok=True)
        write_exr_parts(path, parts, {**attributes, KEY_ATTRIBUTE: key}, part_attributes)
        return path

    def clear(self) -> int:
        """Delete every map file in the folder; the number deleted."""
        if self.root is None or not os.path.isdir(self.root):
            return 0
        removed = 0
        for name in os.listdir(self.root):
            if name.endswith(".exr"):
                os.unlink(os.path.join(self.root, name))
                removed += 1
        return removed


def default_cache_dir(scene_path: str) -> str:
    """`.reflect-cache/` beside the scene file."""
    return os.path.join(os.path.dirname(os.path.abspath(scene_path)), ".reflect-cache")
