"""One writer per output folder: a second bench on the same bench folder, or a second render
on the same frame folder, stops in one line."""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
from collections.abc import Iterator

from ..errors import Problem, Problems
from .names import LOCK_NAME


@contextlib.contextmanager
def folder_lock(folder: str, source: str, field: str = "") -> Iterator[None]:
    """Hold an exclusive lock on `folder` (released when the process ends, however)."""
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, LOCK_NAME)
    try:  # never through a link: it would create a file wherever the link points
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o666)
    except OSError as e:
        if e.errno != errno.ELOOP:
            raise
        raise Problems([Problem(source, field, f"'{path}' is a symbolic link; reflect "
                                "writes no file through a link (remove it)")]) from None
    with _held(fd, folder, source, field, "bench"):
        yield


@contextlib.contextmanager
def frame_folder_lock(folder: str, source: str, field: str = "") -> Iterator[None]:
    """One render per frame folder at a time: a second one stops in one line instead of
    appending its rows among the first's and replacing the frames the first is writing.
    The lock is on the folder itself (flock on its descriptor), so no lock file is left
    among the frames; released when the process ends, however."""
    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW)
    with _held(fd, folder, source, field, "render"):
        yield


@contextlib.contextmanager
def _held(fd: int, folder: str, source: str, field: str, writer: str) -> Iterator[None]:
    """An exclusive flock on `fd` for the body, else one line: another `writer` holds it.
    Closes `fd` either way."""
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise Problems([Problem(source, field, f"{folder} is being written by another "
                                    f"{writer}; wait for it or use another --out")]) from None
        yield
    finally:
        os.close(fd)
