"""Write to a temporary name in the same folder, then rename into place."""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Iterator


def temporary_name(path: str, tag: str = "") -> str:
    """A hidden name beside `path`, unique per process and thread (bench jobs on a Dask
    worker share a process), with its extension: a killed run's leftovers are found by it
    (paths.TEMP)."""
    folder, name = os.path.split(os.path.abspath(path))
    stem, ext = os.path.splitext(name)
    return os.path.join(folder, f".{stem}{tag}.tmp{os.getpid()}-{threading.get_ident()}{ext}")


@contextlib.contextmanager
def temporary_path(path: str) -> Iterator[str]:
    """Yield a temporary name for `path` that the caller renames into place; whatever is
    left at it afterwards is removed."""
    tmp = temporary_name(path)
    try:
        # a link left at the name (it is predictable) would be written through
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        yield tmp
    finally:
        if os.path.lexists(tmp):
            os.unlink(tmp)


def set_aside(path: str) -> str | None:
    """A second name (a hard link) for the file at `path` before a new one replaces it, so
    that it can be put back (`put_back`); None when there is none, or the file system has no
    hard links (the earlier file is then not restorable)."""
    if not os.path.lexists(path):
        return None
    aside = temporary_name(path, "-earlier")
    with contextlib.suppress(FileNotFoundError):
        os.unlink(aside)
    try:
        os.link(path, aside, follow_symlinks=False)
    except OSError:
        return None
    return aside


def drop_aside(aside: str | None) -> None:
    """Remove a second name `set_aside` made (the replacement stands); best effort."""
    if aside is not None:
        with contextlib.suppress(OSError):
            os.unlink(aside)


def put_back(path: str, aside: str | None) -> None:
    """Undo a replacement of `path`: its earlier file back from `aside`, or the new file
    removed when there was none; best effort."""
    with contextlib.suppress(OSError):
        if aside is not None:
            os.replace(aside, path)
        else:
            os.unlink(path)


@contextlib.contextmanager
def atomic_path(path: str) -> Iterator[str]:
    """Yield a temporary path with the same extension; on success it replaces `path`.

    An interrupted or failed write leaves `path` as it was (absent or the previous file)."""
    with temporary_path(path) as tmp:
        yield tmp
        os.replace(tmp, path)  # replaces a link at `path`; never writes through it
