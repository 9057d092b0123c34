"""No file reflect writes is written through a symbolic link, however the link got there:
an append or a lock refuses it, an atomic write replaces the link and leaves its target."""

from __future__ import annotations

import os
import threading

import pytest

from reflectcli.errors import Problems
from reflectcli.output.atomic import atomic_path
from reflectcli.output.failures import WriteFailed
from reflectcli.output.lock import folder_lock
from reflectcli.output.log import append_jsonl

TEXT = "line1\nline2 no newline"


@pytest.fixture
def victim(tmp_path):
    path = tmp_path / "victim.txt"
    path.write_text(TEXT)
    return path


def test_an_append_refuses_a_link(tmp_path, victim):
    (tmp_path / "log.jsonl").symlink_to(victim)
    with pytest.raises(WriteFailed, match="log.jsonl: cannot write .*symbolic link"):
        append_jsonl(str(tmp_path / "log.jsonl"), {"a": 1})
    assert victim.read_text() == TEXT


def test_the_lock_refuses_a_link(tmp_path, victim):
    os.symlink(tmp_path / "elsewhere.lock", tmp_path / ".reflect.lock")
    with pytest.raises(Problems, match="symbolic link"), \
            folder_lock(str(tmp_path), "--out"):
        pass
    assert not (tmp_path / "elsewhere.lock").exists()


def test_an_atomic_write_replaces_a_link_and_its_temporary_name_too(tmp_path, victim):
    target = tmp_path / "frame.txt"
    target.symlink_to(victim)
    # a link at the temporary name (a predictable one) before the write
    (tmp_path / f".frame.tmp{os.getpid()}-{threading.get_ident()}.txt").symlink_to(victim)
    with atomic_path(str(target)) as tmp, open(tmp, "w") as f:
        f.write("new")
    assert victim.read_text() == TEXT
    assert not target.is_symlink() and target.read_text() == "new"
    assert sorted(os.listdir(tmp_path)) == ["frame.txt", "victim.txt"]
