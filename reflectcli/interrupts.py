"""A Ctrl-C (or SIGTERM) that nothing may lose.

Python delivers SIGINT as a KeyboardInterrupt raised wherever the main thread is, and code
that calls back from C (llvmlite's object cache during a numba compile, for one) prints and
drops it: the run would go on and exit 0. So the command line's handler also records the
request here, and the render loop asks at each frame boundary (`check`)."""

from __future__ import annotations

import contextlib
import signal
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


@contextlib.contextmanager
def deferred():
    """Hold Ctrl-C (and SIGTERM, handled alike) until the block ends, then raise it: an
    interrupted run never keeps a frame without its log line. Signal handlers can only be
    set from the main thread; elsewhere the block runs as it is."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list = []
    previous = {sig: signal.signal(sig, lambda *args: caught.append(args))
                for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if caught:
        requested.set()
        raise KeyboardInterrupt
