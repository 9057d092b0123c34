"""Versions, CPU and thread count recorded with every result, so machines can be told apart."""

from __future__ import annotations

import functools
import platform
from importlib import metadata

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
    }


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
