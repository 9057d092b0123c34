"""Timing logs and bench results: one JSON object per line.

An append is atomic: the line is written with one write on a file opened for appending and,
if the write fails or falls short (a full disk), the file is cut back to where it was, so a
log never ends in half a line written by this code. A torn last line (a process killed in
the middle of a write, or an older version) is skipped by the reader with a one-line
notice, and removed by the next append.
"""

from __future__ import annotations

import contextlib
import errno
import json
import logging
import os

from .failures import WriteFailed, reason

log = logging.getLogger("reflect")
LINK = "a symbolic link; reflect writes no file through a link"
HARD_LINK = ("a file with other hard links; reflect appends to no file that has another "
             "name")


def _drop_torn_tail(fd: int, size: int) -> int:
    """Cut an unterminated last line off; the new size."""
    if size == 0 or os.pread(fd, 1, size - 1) == b"\n":
        return size
    chunk = min(size, 1 << 20)
    tail = os.pread(fd, chunk, size - chunk)
    cut = tail.rfind(b"\n")
    new = size - chunk + cut + 1 if cut >= 0 else (0 if chunk == size else size)
    if new != size:
        os.ftruncate(fd, new)
    return new


def append_jsonl(path: str, row: dict) -> None:
    """Append `row` as one line."""
    line = (json.dumps(row, sort_keys=True) + "\n").encode("utf-8")
    try:  # never through a link: it would append outside the folder (paths.check_links)
        fd = os.open(path, os.O_RDWR | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW, 0o666)
    except OSError as e:
        raise WriteFailed(path, LINK if e.errno == errno.ELOOP else reason(e, path)) from None
    try:
        st = os.fstat(fd)
        if st.st_nlink > 1:  # another name for the file, maybe outside the folder
            raise WriteFailed(path, HARD_LINK)
        size = st.st_size
        try:
            size = _drop_torn_tail(fd, size)
            written = os.write(fd, line)
            if written != len(line):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            os.fsync(fd)
        except OSError as e:
            with contextlib.suppress(OSError):
                os.ftruncate(fd, size)
            raise WriteFailed(path, reason(e, path)) from None
    finally:
        os.close(fd)


def read_jsonl(path: str) -> list[dict]:
    """The rows of a JSON-lines file; a line that is not a whole JSON object (a torn last
    line) is skipped and reported in one line."""
    rows = []
    with open(path, encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, 1):
            if not line.strip():
                continue
            try:
                row = json.loads(line)
            except json.JSONDecodeError:
                row = None
            if not isinstance(row, dict):
                log.warning("%s: line %d is not a whole record (a write cut short?); skipped",
                            path, number)
                continue
            rows.append(row)
    return rows
