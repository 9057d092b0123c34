"""A Ctrl-C (or SIGTERM) that nothing may lose.

Python delivers SIGINT as a KeyboardInterrupt raised wherever the main thread is, and code
that calls back from C (llvmlite's object cache during a numba compile, for one) prints and
drops it: the run would go on and exit 0. So the command line's handler also records the
request here, and the render loop asks at each frame boundary (`check`)."""

from __future__ import annotations

import threading

requested = threading.Event()


def on_signal(signum, frame) -> None:
    """Signal handler: remember the request, then interrupt whatever runs."""
    requested.set()
    raise KeyboardInterrupt


def check() -> None:
    """Raise KeyboardInterrupt if an interrupt was requested, even one somebody swallowed."""
    if requested.is_set():
        raise KeyboardInterrupt
