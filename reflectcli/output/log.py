"""Timing logs: one JSON object per line, appended with a single write."""

from __future__ import annotations

import json
import os


def append_jsonl(path: str, row: dict) -> None:
    line = json.dumps(row, sort_keys=True) + "\n"
    with open(path, "a", encoding="utf-8") as f:
        f.write(line)
        f.flush()
        os.fsync(f.fileno())


def read_jsonl(path: str) -> list[dict]:
    with open(path, encoding="utf-8") as f:
        return [json.loads(line) for line in f if line.strip()]
