"""Reading the files a scene names: only regular files, with a size limit, and TOML with a
depth limit, so a named pipe, /dev/zero, a directory, a NUL byte or a deeply nested file
ends in one line naming the file instead of a hang, an out-of-memory kill or a traceback."""

from __future__ import annotations

import os
import stat

import tomli

from ..errors import Problem, Problems
from .limits import MAX_NESTING, MAX_TOML_BYTES


def display_path(path: str) -> str:
    """A path as messages name it: relative to the working directory unless that climbs."""
    try:
        rel = os.path.relpath(path)
    except ValueError:
        return path
    return path if rel.startswith("..") else rel


def file_problem(path: str, limit: int, what: str = "file") -> str | None:
    """Why `path` cannot be read as a regular file of at most `limit` bytes (a reason without
    the path: callers add the name they show), or None."""
    if "\0" in path:
        return "path contains a NUL byte"
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return "file not found"
    except OSError as e:
        return f"cannot read ({e.strerror})"
    if stat.S_ISDIR(st.st_mode):
        return f"a directory, not a {what}"
    if not stat.S_ISREG(st.st_mode):
        return "not a regular file (a pipe, device or socket)"
    if st.st_size > limit:
        return f"{st.st_size} bytes, over the limit of {limit} for a {what}"
    return None


def read_regular(path: str, limit: int, file: str, field: str, what: str = "file",
                 name: str | None = None) -> bytes:
    """The bytes of a regular file of at most `limit` bytes, else Problems(file, field): the
    message ends with `name` (how the problem's file refers to this one) when given."""
    reason = file_problem(path, limit, what)
    if reason is None:
        try:
            fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
            try:
                if not stat.S_ISREG(os.fstat(fd).st_mode):  # swapped after the stat
                    reason = "not a regular file"
                else:
                    with os.fdopen(fd, "rb", closefd=False) as f:
                        data = f.read(limit + 1)
                    if len(data) > limit:
                        reason = f"over the limit of {limit} bytes for a {what}"
            finally:
                os.close(fd)
        except OSError as e:
            reason = f"cannot read ({e.strerror})"
    if reason is not None:
        shown = name if name is not None else path if "\0" not in path else None
        raise Problems([Problem(file, field, f"{reason}: {shown}" if shown and name else reason)])
    return data


def depth_problem(data) -> tuple[str, int] | None:
    """(dotted path, depth) of the first place a parsed document nests past MAX_NESTING."""
    stack = [(data, (), 0)]
    while stack:
        node, path, depth = stack.pop()
        if depth > MAX_NESTING:
            return ".".join(str(p) for p in path[:4]) + "...", depth
        if isinstance(node, dict):
            stack.extend((v, (*path, k), depth + 1) for k, v in node.items())
        elif isinstance(node, list):
            stack.extend((v, (*path, i), depth + 1) for i, v in enumerate(node))
    return None


def parse_toml(text: bytes, display: str) -> dict:
    """A TOML document (UTF-8), nested at most MAX_NESTING levels; Problems naming the file."""
    try:
        data = tomli.loads(text.decode("utf-8"))
    except UnicodeDecodeError as e:
        raise Problems([Problem(display, "", f"not UTF-8 text: {e.reason}")]) from None
    except tomli.TOMLDecodeError as e:
        raise Problems([Problem(display, "", f"TOML syntax error: {e}")]) from None
    except ValueError as e:  # an integer of over 4300 digits: Python's int() refuses it
        raise Problems([Problem(display, "", f"a number too long to read ({_first(e)})")]
                       ) from None
    except RecursionError:
        raise Problems([Problem(display, "", f"nested more than {MAX_NESTING} levels deep")]
                       ) from None
    deep = depth_problem(data)
    if deep is not None:
        raise Problems([Problem(display, deep[0], f"nested more than {MAX_NESTING} levels deep")])
    return data


def _first(error: Exception) -> str:
    """The part of a library's message that says what is wrong (before its advice)."""
    return str(error).split(";")[0].strip()


def read_toml_file(path: str, field: str = "", referrer: str | None = None) -> dict:
    """Read a TOML file the scene names. Problems about reaching the file name the referrer
    (the file that names it) when given; problems inside it name the file itself."""
    display = display_path(path)
    text = read_regular(path, MAX_TOML_BYTES, referrer or display, field, "TOML file",
                        path if referrer else None)
    return parse_toml(text, display)
