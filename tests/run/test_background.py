"""The background writer (pedmesh.run.background): the writing calls made on a thread of
its own, in order, with the arrays as they were when the call was made; a failed write
ends the run as in the foreground; nothing queued is lost."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from pedmesh.run.background import MAX_PENDING, BackgroundWriter, use_background
from pedmesh.run.memory import MemoryWriter
from pedmesh.run.output import OutputWriteError


class Recorder:
    """A writer that keeps its calls (and the thread that made them)."""

    dir = "somewhere"

    def __init__(self, fail_at: int | None = None, delay: float = 0.0) -> None:
        self.calls: list = []
        self.fail_at = fail_at
        self.delay = delay
        self.finished: dict | None = None

    def _note(self, name, *args):
        if self.fail_at is not None and len(self.calls) == self.fail_at:
            raise OutputWriteError(28, "No space left on device", "frame.vtu")
        time.sleep(self.delay)
        self.calls.append((name, threading.current_thread().name, args))

    def sample(self, t, evacuated):
        self._note("sample", t, evacuated)

    def pedestrian_frame(self, t, points, data):
        self._note("pedestrian_frame", t, points, data)

    def call(self, fn, *args):
        fn(self, *args)

    def start(self, header=None):
        self.calls.append(("start", threading.current_thread().name, ()))

    def finish(self, **summary):
        self.finished = summary
        return summary


def test_calls_in_order_on_their_own_thread_with_the_arrays_as_they_were():
    rec = Recorder(delay=0.002)
    w = BackgroundWriter(rec)
    w.start()  # (not a write: made at once, on this thread)
    x = np.zeros((3, 2))
    data = {"speed": np.ones(3)}
    for k in range(10):
        x[:] = k
        data["speed"][:] = -k
        w.pedestrian_frame(0.1 * k, x, data)
        w.sample(0.1 * k, k)
        w.call(lambda inner, k=k: inner.sample(-1.0, k))
    x[:] = 99  # (after the calls: not what they write)
    w.finish(status="finished")
    assert rec.finished == {"status": "finished"}
    names = [c[0] for c in rec.calls]
    assert names == ["start"] + ["pedestrian_frame", "sample", "sample"] * 10
    assert rec.calls[0][1] == threading.current_thread().name
    assert {c[1] for c in rec.calls[1:]} == {"pedmesh-writer"}
    frames = [c[2] for c in rec.calls if c[0] == "pedestrian_frame"]
    for k, (t, points, d) in enumerate(frames):
        assert t == 0.1 * k and np.all(points == k) and np.all(d["speed"] == -k)
    assert [c[2] for c in rec.calls if c[0] == "sample"][1::2] == [(-1.0, k) for k in
                                                                 range(10)]


def test_drain_waits_for_every_call():
    rec = Recorder(delay=0.005)
    w = BackgroundWriter(rec)
    for k in range(30):
        w.sample(float(k), k)
    assert w.pending > 0  # (the writer is behind)
    w.drain()
    assert w.pending == 0 and len(rec.calls) == 30
    w.finish(status="finished")


def test_a_full_queue_holds_the_caller_back():
    rec = Recorder(delay=0.002)
    w = BackgroundWriter(rec)
    for k in range(3 * MAX_PENDING):
        w.sample(float(k), k)
        assert w.pending <= MAX_PENDING + 1  # (the queue and the call being written)
    w.finish(status="finished")
    assert len(rec.calls) == 3 * MAX_PENDING


def test_a_failed_write_is_raised_once_and_fails_the_run():
    rec = Recorder(fail_at=3)
    w = BackgroundWriter(rec)
    with pytest.raises(OutputWriteError, match="frame.vtu"):
        for k in range(50):
            w.sample(float(k), k)
            time.sleep(0.001)
    assert len(rec.calls) == 3
    w.sample(99.0, 99)  # (after the error nothing more is written, nor raised again)
    w.finish(status="finished")
    assert len(rec.calls) == 3 and rec.finished["status"] == "finished"


def test_a_failure_found_at_the_end_fails_the_summary():
    rec = Recorder(fail_at=1)
    w = BackgroundWriter(rec)
    w.sample(0.0, 0)
    w.sample(0.1, 1)
    summary = w.finish(status="finished")
    assert summary["status"] == "failed" and "frame.vtu" in summary["error"]


def test_when_the_background_is_used():
    mem = MemoryWriter({"model": "sfm"})
    assert not use_background(2, mem)  # (output kept in memory: nothing to overlap)
    assert not use_background(1, Recorder())
    assert use_background(2, Recorder())


@pytest.mark.skipif(__import__("numba").config.NUMBA_NUM_THREADS < 2,
                    reason="numba has fewer than 2 threads here")
def test_a_continuum_run_writes_the_same_files_in_the_background(geometries_dir, tmp_path):
    """eos on 1 thread (output in the foreground) and on 2 (on the writer thread): every
    file but the summary byte for byte."""
    from pedmesh.cli import main

    files = {}
    for threads in (1, 2):
        out = tmp_path / f"t{threads}"
        assert main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--model",
                     "eos", "--t-end", "6", "--param", f"threads={threads}", "--out",
                     str(out), "-q"]) == 0
        files[threads] = {str(f.relative_to(out)): f.read_bytes() for f in out.rglob("*")
                          if f.is_file() and f.name not in ("summary.json", ".lock")}
    assert {"evacuation.csv", "outflow.csv", "density.pvd"} <= set(files[1])
    assert len([f for f in files[1] if f.endswith(".vtu")]) > 3
    assert files[1] == files[2]


def test_close_twice_and_a_ctrl_c_while_it_waits(monkeypatch):
    """A Ctrl-C while close waits for the writer thread: it goes on waiting, and every
    call is written; a second close does nothing."""
    rec = Recorder(delay=0.003)
    w = BackgroundWriter(rec)
    for k in range(20):
        w.sample(float(k), k)
    joins = []
    real_join = w._thread.join

    def join(*args):
        joins.append(1)
        if len(joins) == 1:
            raise KeyboardInterrupt
        return real_join(*args)

    monkeypatch.setattr(w._thread, "join", join)
    w.close()
    assert len(joins) == 2 and len(rec.calls) == 20 and not w._thread.is_alive()
    w.close()
    assert w.finish(status="finished") == {"status": "finished"}
