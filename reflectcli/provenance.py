"""Versions, CPU and thread count recorded with every result, so machines can be told apart."""

from __future__ import annotations

import functools
import hashlib
import platform
from importlib import metadata
from pathlib import Path

from . import __version__


def _version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "unknown"


@functools.lru_cache(maxsize=1)
def versions() -> dict[str, str]:
    import numba

    return {
        "reflect": __version__,
        "python": platform.python_version(),
        "numba": numba.__version__,
        "numpy": _version("numpy"),
        "openimageio": _version("OpenImageIO"),
        "embreex": _version("embreex"),
        "embree": "4 (embreex " + _version("embreex") + ")",
        "source": source_digest(),
    }


@functools.lru_cache(maxsize=1)
def source_digest() -> str:
    """A digest of reflect's own files (its modules and bundled data): the version number is
    not raised per change, so two results with the same digest ran the same code, and a
    bench reuses a reference's frames and times only under the same digest (bench/runner)."""
    package = Path(__file__).resolve().parent
    digest = hashlib.blake2b(digest_size=8)
    for path in sorted(p for p in package.rglob("*") if p.is_file()
                       and p.suffix in (".py", ".json", ".ply")
                       and "__pycache__" not in p.parts):
        digest.update(path.relative_to(package).as_posix().encode() + b"\0")
        digest.update(path.read_bytes())
    return digest.hexdigest()


@functools.lru_cache(maxsize=1)
def cpu_name() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()
