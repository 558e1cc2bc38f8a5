"""Helpers shared by the benchmark scripts (run them as ``python benchmarks/NAME.py``)."""

from __future__ import annotations

import time


def run_to_end(run, t_max: float = 900.0) -> tuple[float, float | None]:
    """Step a run until everyone has left or ``t_max`` [s] of simulated time; returns the
    wall time [s] and the wall time to 99 % evacuated (None if not reached)."""
    t0 = time.perf_counter()
    t99 = None
    while not run.done and run.t < t_max:
        run.step()
        if t99 is None and run.evacuated >= 0.99 * run.n_initial:
            t99 = time.perf_counter() - t0
    return time.perf_counter() - t0, t99
