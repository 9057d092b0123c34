"""C libraries' own stderr lines (libpng's "libpng error: ...") caught, so that a failure
is reported in one line that quotes them."""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from collections.abc import Iterator


@contextlib.contextmanager
def c_stderr(said: list[str]) -> Iterator[None]:
    """What C libraries write to the process's stderr meanwhile (libpng prints its own
    "libpng error: ..." line before OpenImageIO fails) goes into `said`, not the terminal:
    the failure is reported in one line that quotes it. Textures load while the scene is
    built, before any other thread writes (and `compare` reads its two images alone)."""
    sys.stderr.flush()
    try:
        saved = os.dup(2)
    except OSError:  # no stderr to redirect
        yield
        return
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            said.extend(line.strip() for line in
                        sink.read(4096).decode("utf-8", "replace").splitlines() if line.strip())
