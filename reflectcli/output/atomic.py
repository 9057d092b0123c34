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
        # a link left at the name (it is predictable) would be written through
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        yield tmp
        os.replace(tmp, path)  # replaces a link at `path`; never writes through it
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
