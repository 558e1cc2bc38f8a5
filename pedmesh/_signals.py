"""Stop requests: Ctrl-C and SIGTERM ask a long computation to stop at its next step.

A module of its own, below everything that runs long (the run driver, the calibration), so
that each of them can check for a stop without importing the others.
"""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager
from typing import Any, Iterator

__all__ = ["request_stop", "stop_requested", "stop_on_signals"]

#: set by :func:`request_stop`; runs check it between steps
_STOP = threading.Event()


def request_stop(signum: int | None = None, frame: Any = None) -> None:
    """Ask the running model to stop after its current step (a signal handler).

    The run then ends as if interrupted, with everything up to that step written. A second
    request before the run has stopped interrupts at once (KeyboardInterrupt). Raising from
    the handler itself would interrupt compiled kernels in the middle of a call, which
    numba reports as an unrelated SystemError.
    """
    if _STOP.is_set():
        raise KeyboardInterrupt
    _STOP.set()


def stop_requested() -> bool:
    """Whether a stop was requested (long computations check it between their steps)."""
    return _STOP.is_set()


@contextmanager
def stop_on_signals(signals: tuple[int, ...] = (signal.SIGINT, signal.SIGTERM)) -> Iterator[None]:
    """Within the block, Ctrl-C and SIGTERM stop a run at the next step boundary."""
    _STOP.clear()
    old = {s: signal.signal(s, request_stop) for s in signals}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        _STOP.clear()
