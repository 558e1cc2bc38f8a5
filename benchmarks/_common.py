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


def write_json(path, results: dict) -> None:
    """Write a benchmark's figures with how and where they were measured: the command line,
    the date, the machine (CPU count, platform, load average), the Python and pedmesh
    versions. The docs render their tables from such files (``docs/render_figures.py``)."""
    import datetime
    import json
    import os
    import platform
    import sys
    from pathlib import Path

    import pedmesh

    record = {
        "command": "python " + " ".join([Path(sys.argv[0]).as_posix(), *sys.argv[1:]]),
        "date": datetime.date.today().isoformat(),
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform(),
                    "processor": platform.processor() or platform.machine(),
                    # other load on a shared machine at the end of the run (1, 5, 15 min)
                    "load_average": [round(x, 2) for x in os.getloadavg()]},
        "python": platform.python_version(),
        "pedmesh": pedmesh.__version__,
        "results": results,
    }
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text(json.dumps(record, indent=1) + "\n")
    print(f"wrote {path}")
