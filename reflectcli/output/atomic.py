"""Write to a temporary name in the same folder, then rename into place."""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Iterator


@contextlib.contextmanager
def atomic_path(path: str) -> Iterator[str]:
    """Yield a temporary path with the same extension; on success it replaces `path`.

    An interrupted or failed write leaves `path` as it was (absent or the previous file)."""
    folder, name = os.path.split(os.path.abspath(path))
    stem, ext = os.path.splitext(name)
    # unique per process and thread: bench jobs on a Dask worker share a process
    tmp = os.path.join(folder, f".{stem}.tmp{os.getpid()}-{threading.get_ident()}{ext}")
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
