"""Output paths: every file stays inside its output folder, and the temporary files of runs
that were killed (see atomic.py for their names) are removed by the next run there."""

from __future__ import annotations

import contextlib
import os
import re
import stat
import tempfile
from collections.abc import Iterable

from ..errors import Problem, Problems
from .atomic import temporary_name
from .names import FRAME, SUMMARY_NAME, taken_by

# exactly what atomic.py names its temporary files, .<stem>.tmp<pid>-<thread id><ext>, with
# the extensions reflect writes through it (a user's `.notes.tmp123` is not one of them);
# log appends write in place (log.py) and leave no temporary file
TEMP = re.compile(r"^\..+\.tmp(?P<pid>[0-9]{1,10})-[0-9]{1,20}\.(exr|png|json|csv|md)$")


def inside(folder: str, name: str, source: str = "output", field: str = "") -> str:
    """`folder/name`, refused in one line unless it stays inside `folder`. A folder that
    normalises to the working directory (`.`, `lk/..`: paths are joined and normalised, see
    check_links) holds `name` too: its joined path has no directory part."""
    path = os.path.normpath(os.path.join(folder, name))
    root = os.path.normpath(folder)
    if (os.path.dirname(path) or os.curdir) != root or os.path.basename(path) in (
            "", ".", ".."):
        raise Problems([Problem(source, field, f"'{name}' would be written outside {folder}")])
    return path


def check_links(root: str, folder: str, log: str, source: str, field: str,
                log_source: str, frames: Iterable[int] | None = None) -> None:
    """Refuse in one line, before anything is written: a folder between `root` and the frame
    `folder` that resolves outside `root` (a link: the frames would land elsewhere), a
    link in `folder` at a name reflect writes (the log, the summary, the lock, a frame): an
    append would follow it out of the folder, and a replace would drop the link; and a
    directory (or pipe, socket, ...) at the log's, the summary's or the name of a frame in
    `frames` (None: any frame), which no write could replace. `log_source` names the file
    output.log came from."""
    # the root as the frames' paths reach it: normalised first, as `inside` joins them
    # (`build/../out` with `build` a link is ./out, not the link's sibling)
    path = os.path.normpath(root)
    top = os.path.realpath(path)
    for part in os.path.relpath(os.path.normpath(folder), path).split(os.sep):
        path = os.path.join(path, part)
        if not os.path.lexists(path):
            break
        real = os.path.realpath(path)
        if os.path.commonpath([top, real]) != top:
            raise Problems([Problem(source, field, f"'{path}' leads to '{real}', outside "
                                    f"{root}; reflect writes nothing outside its output "
                                    "folder")])
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return  # not made yet: no link in it
    wanted = None if frames is None else {f"frame_{i:04d}{ext}" for i in frames
                                          for ext in (".exr", ".png")}
    for entry in entries:
        where = (log_source, "output.log") if entry.name == log else (source, field)
        if entry.is_symlink() and (entry.name == log or taken_by(entry.name)):
            raise Problems([Problem(*where, f"'{entry.path}' is a symbolic link; reflect "
                                    "writes no file through a link (remove it)")])
        if not entry.is_symlink() and not entry.is_file() and _written(entry.name, log,
                                                                         wanted):
            kind = "a directory" if entry.is_dir() else "not a regular file"
            raise Problems([Problem(*where, f"'{entry.path}' is {kind}; reflect writes "
                                    f"{taken_by(entry.name) or 'the log'} there "
                                    "(remove it)")])
    _check_log_hard_links(os.path.join(folder, log), log_source)


def _written(name: str, log: str, frames: set[str] | None) -> bool:
    """Whether a render writes a file at `name` in its frame folder (frames: the frame
    files of the range rendered; None: any)."""
    if name == log or name.casefold() == SUMMARY_NAME:
        return True
    if FRAME.match(name.casefold()):
        return frames is None or name in frames
    return False


def _check_log_hard_links(log: str, log_source: str) -> None:
    """The log is appended to in place: with another hard link (a name maybe outside the
    output folder) the rows would land in that file too. Frames are replaced by a rename,
    which drops a link instead of writing through it."""
    try:
        st = os.lstat(log)
    except OSError:
        return
    if stat.S_ISREG(st.st_mode) and st.st_nlink > 1:
        raise Problems([Problem(log_source, "output.log", f"'{log}' has other hard links; "
                                "reflect appends to no file that has another name "
                                "(copy it, or remove it)")])


def _nearest_existing(folder: str) -> str:
    """`folder` or its nearest ancestor that exists (absolute)."""
    existing = os.path.abspath(folder)
    while not os.path.lexists(existing) and os.path.dirname(existing) != existing:
        existing = os.path.dirname(existing)
    return existing


def _unwritable(folder: str, source: str, field: str, reason: str) -> Problems:
    return Problems([Problem(source, field, f"cannot write to '{folder}': {reason}")])


def check_writable(folder: str, source: str, field: str) -> None:
    """Refuse in one line a folder that a render could not create or write into, leaving
    nothing behind (`validate`): its nearest existing ancestor must be a directory in which
    a directory can be made (one is made and removed at once: permission bits alone pass
    /proc for root, where render's makedirs then fails). Render itself makes no such probe:
    it makes the folder (make_folder), locks it, then proves it (prove_writable)."""
    existing = _nearest_existing(folder)
    if not os.path.isdir(existing):
        reason = "Not a directory"
    else:  # the OS's own reason (os.access said "Permission denied" on a read-only mount)
        try:
            made = tempfile.mkdtemp(prefix=".reflect-validate-", dir=existing)
        except OSError as e:
            reason = e.strerror or str(e)
        else:
            with contextlib.suppress(OSError):
                os.rmdir(made)
            return
    raise _unwritable(folder, source, field, reason)


def make_folder(folder: str, source: str, field: str) -> None:
    """Create `folder` and its parents for a render (which must exist to be locked), refused
    in check_writable's line when that fails; nothing else is written."""
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as e:
        # a file in the way is "Not a directory" whether it is the folder or an ancestor
        # (makedirs says "File exists" for the one), as validate says
        reason = ("Not a directory" if not os.path.isdir(_nearest_existing(folder))
                  else e.strerror or str(e))
        raise _unwritable(folder, source, field, reason) from None


def prove_writable(folder: str, source: str, field: str) -> None:
    """Refuse in one line a `folder` no file can be made in, as check_writable would: a
    render calls it with the folder locked, so that its probe (a temporary name,
    atomic.py's) never lands in a folder another render is writing; the probe is removed at
    once, and a killed run's is a stale temporary file the next run removes."""
    probe = temporary_name(os.path.join(folder, "write-test.json"))
    try:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(probe)  # a killed run's (a read-only folder refuses even this: EROFS)
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o666)
    except OSError as e:
        raise _unwritable(folder, source, field, e.strerror or str(e)) from None
    try:
        os.close(fd)
    finally:
        os.unlink(probe)


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_stale_temps(folder: str, pattern: re.Pattern = TEMP) -> list[str]:
    """Delete temporary files left in `folder` by processes that no longer run (names that
    `pattern` matches, its `pid` group the writer's); their names."""
    removed = []
    try:
        names = os.listdir(folder)
    except OSError:
        return removed
    for name in names:
        m = pattern.match(name)
        if m and not _alive(int(m.group("pid"))):
            with contextlib.suppress(OSError):
                os.unlink(os.path.join(folder, name))
                removed.append(name)
    return removed
