"""A run's output written on a thread of its own, while the model steps on.

Once a model's steps run on several threads, writing its output (trajectories.txt and
.sqlite, the VTK frames, the CSV series) on the stepping thread leaves the other cores
idle while it formats and writes. :class:`BackgroundWriter` takes the writing calls of a
:class:`~pedmesh.run.output.RunWriter`, copies their arrays (the model may change its own
in place on its next step) and hands them to one writer thread, which makes the calls in
the order they came: the files are byte for byte those of the same run written in the
foreground.

* Nothing is lost: :meth:`drain` waits until every call made so far is written (the run
  calls it before it reads its own output back, e.g. for the safety measures), and
  :meth:`finish` drains, then closes the files and writes the summary as the
  :class:`RunWriter` does. A Ctrl-C while it drains does not drop the queue.
* A write that fails (a full disk) stops the writer thread; the error is raised on the
  stepping thread at its next call, as the foreground writer would have raised it.
* The queue holds at most :data:`MAX_PENDING` calls: a writer slower than the model holds
  the model back rather than filling the memory.

The driver uses it when the run has more than one thread (:func:`use_background`).
"""

from __future__ import annotations

import queue
import threading
from typing import Any, Callable, Mapping

import numpy as np

from ..io.run_folder import QUEUED_WRITES, WRITER_METHODS

__all__ = ["BackgroundWriter", "MAX_PENDING", "use_background"]

#: calls waiting to be written before the stepping thread waits for the writer
MAX_PENDING = 64

#: the writer methods that only write (and return nothing): these go to the thread (the
#: queued writes of the writer protocol, :data:`pedmesh.io.run_folder.WRITER_METHODS`)
WRITES = QUEUED_WRITES

_STOP = object()


def use_background(threads: int | None, writer: Any) -> bool:
    """Write in the background: a run on more than one thread (``threads``: the
    ``threads`` parameter, None: numba's count) writing to disk (a writer with a folder,
    not one that keeps its output in memory)."""
    if getattr(writer, "dir", None) is None:
        return False
    if threads is None:
        import numba

        threads = numba.get_num_threads()
    return int(threads) > 1


#: types passed on as they are (nothing in them the model could change)
_PLAIN = (float, int, str, bool, type(None), np.floating, np.integer)


def _own(value: Any) -> Any:
    """``value`` with its arrays copied (also those in a dict or a list), so that the model
    may change its own before the call is written."""
    if isinstance(value, _PLAIN):
        return value
    if isinstance(value, np.ndarray):
        return value.copy()
    if isinstance(value, Mapping):
        return {k: _own(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        if all(isinstance(v, _PLAIN) for v in value):  # (a call's numbers, a sample's)
            return value if isinstance(value, tuple) else type(value)(value)
        return type(value)(_own(v) for v in value)
    return value


class BackgroundWriter:
    """The writing calls of ``writer`` made on a thread of its own, in order (see the module
    docstring); every other attribute is the writer's own."""

    def __init__(self, writer: Any) -> None:
        self._writer = writer
        self._queue: queue.Queue = queue.Queue(maxsize=MAX_PENDING)
        self._error: BaseException | None = None
        self._failed = False
        self._thread = threading.Thread(target=self._work, name="pedmesh-writer", daemon=True)
        self._thread.start()

    def _work(self) -> None:
        while True:
            job = self._queue.get()
            try:
                if job is _STOP:
                    return
                if self._error is None:
                    fn, args, kwargs = job
                    fn(*args, **kwargs)
            except BaseException as exc:  # kept for the stepping thread
                self._error = exc
            finally:
                self._queue.task_done()

    def _raise(self) -> None:
        """Raise a write error of the writer thread (once; it writes nothing more)."""
        if self._error is not None:
            exc, self._error = self._error, None
            self._failed = True
            raise exc

    def _submit(self, fn: Callable, args: tuple, kwargs: dict) -> None:
        self._raise()
        if not self._failed:
            self._queue.put((fn, _own(args), _own(kwargs)))

    def __getattr__(self, name: str) -> Any:
        attr = getattr(self._writer, name)
        if name in WRITES:
            def submit(*args, **kwargs):
                self._submit(attr, args, kwargs)

            self.__dict__[name] = submit  # (found there from now on, without this call)
            return submit
        if callable(attr) and not name.startswith("_") and name not in WRITER_METHODS:
            # (a write method nobody declared would run here, out of order with the queue)
            raise TypeError(f"{type(self._writer).__name__}.{name} is not a method of the "
                            "writer protocol (pedmesh.io.run_folder.WRITER_METHODS); declare "
                            "it queued or immediate there")
        return attr

    @property
    def pending(self) -> int:
        """Calls not written yet."""
        return self._queue.unfinished_tasks

    def drain(self, *, raise_error: bool = True) -> None:
        """Wait until every call made so far is written; raise the first write error (else
        it is left for :meth:`finish`)."""
        while True:
            try:
                self._queue.join()
                break
            except KeyboardInterrupt:  # the queue is written all the same
                continue
        if raise_error:
            self._raise()

    def close(self) -> None:
        """Drain and stop the writer thread (idempotent)."""
        sent = False
        while self._thread.is_alive():
            try:
                if not sent:  # (once: after it the thread takes nothing more)
                    self._queue.put(_STOP)
                    sent = True
                self._thread.join()
            except KeyboardInterrupt:  # what is queued is written all the same
                continue

    def finish(self, **summary: Any) -> dict[str, Any]:
        """Write what is queued, then close the files and write the summary (the writer's
        :meth:`~pedmesh.run.output.RunWriter.finish`); a write that failed in the
        background marks the run failed with its error."""
        self.close()
        exc = self._error
        self._error = None
        if exc is not None and summary.get("status") != "failed":
            summary = {**summary, "status": "failed", "error": str(exc)}
        return self._writer.finish(**summary)
