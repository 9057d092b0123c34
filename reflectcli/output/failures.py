"""Write failures (a full disk, a read-only folder, a vanished file) as one line naming the
file and the operating system's reason, never a traceback."""

from __future__ import annotations

import contextlib
import errno
import os
import shutil


class WriteFailed(OSError):
    """`<file>: cannot write (<reason>)`; what was being written is left as it was."""

    def __init__(self, path: str, reason: str) -> None:
        super().__init__(f"{path}: cannot write ({reason})")
        self.path, self.reason = path, reason

    def __reduce__(self):  # picklable: a bench worker process sends it back
        return (WriteFailed, (self.path, self.reason))


def reason(e: BaseException, path: str) -> str:
    """The OS reason for a failed write: strerror, else the library's first line, else (an
    image library that lost errno) a full disk if the folder has no space left."""
    if isinstance(e, WriteFailed):
        return e.reason
    if isinstance(e, OSError) and e.strerror:
        return e.strerror
    text = str(e).strip().splitlines()[0] if str(e).strip() else ""
    prefix = f"cannot write {path}:"
    text = text[len(prefix):].strip() if text.startswith(prefix) else text
    with contextlib.suppress(OSError):
        if shutil.disk_usage(os.path.dirname(os.path.abspath(path)) or ".").free < 1 << 16:
            return os.strerror(errno.ENOSPC)
    return text or "unknown error"


def write_failure(e: BaseException, path: str) -> WriteFailed:
    return e if isinstance(e, WriteFailed) else WriteFailed(path, reason(e, path))


def image_failure(path: str, error: str) -> WriteFailed:
    """An image library's failure to write `path`, as WriteFailed. Called while the partial
    temporary file is still on disk: once it is removed, a full disk no longer looks full
    and the reason would be "unknown error"."""
    return WriteFailed(path, reason(OSError(error), path))


def one_line(e: BaseException) -> str:
    text = str(e).strip()
    return text.splitlines()[0] if text else type(e).__name__
