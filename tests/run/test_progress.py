"""The progress bar's estimate of the time left (pedmesh.run.progress): none before the
first person is out, then within a factor of two of the truth from 20 % out on."""

from __future__ import annotations

import json
import time
from types import SimpleNamespace

import pytest

import pedmesh
from pedmesh.run import progress
from pedmesh.run.progress import EvacuationBar


def _bar(total: int) -> EvacuationBar:
    return EvacuationBar(total=total, disable=False, file=open("/dev/null", "w"),
                         mininterval=0.0)


def test_no_estimate_before_the_first_person_is_out(monkeypatch):
    clock = iter(range(100))
    monkeypatch.setattr(progress.time, "perf_counter", lambda: float(next(clock)))
    bar = _bar(100)
    for t in (0.5, 1.0, 1.5):
        bar.advance(0, t)
        assert bar.time_left() is None
    assert "?" in str(bar)  # (tqdm's sign for an unknown time left)
    bar.close()


def test_the_estimate_of_a_steady_evacuation(monkeypatch):
    """10 people per simulated second leave; a simulated second costs 0.01 wall s per
    person inside: the time left at N inside is the integral 0.01 N^2 / (2 * 10)."""
    now = [0.0]
    monkeypatch.setattr(progress.time, "perf_counter", lambda: now[0])
    bar = _bar(1000)
    out, t = 0.0, 0.0
    while out < 600:
        dt = 0.5
        now[0] += dt * 0.01 * (1000 - out - 2.5)  # (the mean inside over the half second)
        t += dt
        out += 10 * dt
        bar.advance(out, t)
    # the truth: 0.01 N^2 / (2 * 10); the estimate takes a cost between staying and
    # falling in proportion to N (progress.FALLING_COST)
    left = 0.01 * (1000 - out) ** 2 / 20
    assert bar.time_left() == pytest.approx(left * 2 * progress.FALLING_COST, rel=0.05)
    assert left < bar.time_left() < 2 * left
    assert bar.n == 600
    bar.close()


def test_the_time_left_of_a_run_is_within_twice_the_truth(tmp_path, monkeypatch):
    """A small room (400 people, a 2 m door; a few seconds of wall time): every estimate from
    20 % out on, while at least a second is left (the bar shows whole seconds), within a
    factor of two of the time the run then took. The bar's clock, and the test's, is the
    process's CPU time: the suite runs in two processes, and the other one's load, which
    comes and goes, changes the pace of the wall clock mid-run, not the estimator's work
    (on a quiet machine the two clocks keep one pace)."""
    room = tmp_path / "room.json"
    room.write_text(json.dumps({
        "format": "pedmesh-room", "version": 1, "name": "eta_room", "units": "m",
        "outline": [[0, 0], [20, 0], [20, 16], [0, 16]],
        "exits": [{"name": "door", "polyline": [[20, 7], [20, 9]]}],
        "start_areas": [{"name": "crowd", "polygon": [[1, 1], [15, 1], [15, 15], [1, 15]],
                         "count": 400}]}))
    seen: list[tuple[float, float, float | None]] = []
    closed: list[float] = []

    class Watched(EvacuationBar):
        def advance(self, out, t_sim):
            super().advance(out, t_sim)
            seen.append((time.process_time(), self.n / self.total, self.time_left()))

        def close(self):
            closed.append(time.process_time())
            super().close()

    monkeypatch.setattr(progress, "time", SimpleNamespace(perf_counter=time.process_time))
    monkeypatch.setattr(progress, "EvacuationBar", Watched)
    pedmesh.simulate(room, model="sfm", preset="validated", seed=0, quiet=False)
    end = closed[0]
    ratios = [left / (end - t) for t, frac, left in seen if frac >= 0.2 and end - t >= 1.0]
    assert len(ratios) >= 5
    assert all(0.5 <= r <= 2.0 for r in ratios), ratios
