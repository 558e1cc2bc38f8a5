"""Run any registered model through the shared output contract, with a progress bar."""

from __future__ import annotations

import math
import signal
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

from ..errors import SimulationError
from .models import get_model
from .output import RunWriter

__all__ = ["run_model", "RunInterrupted", "request_stop", "stop_requested", "stop_on_signals"]

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


class RunInterrupted(Exception):
    """A run stopped by Ctrl-C or SIGTERM; the output written so far is kept."""

    def __init__(self, t: float, out_dir: Path) -> None:
        super().__init__(f"interrupted at t = {t:.2f} s; results up to then are in {out_dir}")
        self.t = t
        self.out_dir = out_dir


def run_model(room, mesh, model: str, *, overrides: dict[str, float] | None = None,
              t_end: float = 1000.0, out_dir: str | Path = "run", quiet: bool = False,
              geometry: str | None = None, mesh_options: dict[str, Any] | None = None,
              model_options: dict[str, Any] | None = None) -> dict[str, Any]:
    """Run ``model`` on ``mesh`` until everyone has left or ``t_end`` [s].

    Writes the output directory incrementally (see :mod:`pedmesh.run.output`) and returns
    the final summary. Raises :class:`RunInterrupted` on Ctrl-C or :func:`request_stop`
    (after writing the summary) and :class:`~pedmesh.errors.SimulationError` on a blow-up
    (likewise).
    """
    from tqdm import tqdm

    if stop_requested():  # asked to stop before this run began (e.g. between compared models)
        raise KeyboardInterrupt
    if not (math.isfinite(t_end) and t_end > 0):
        raise SimulationError(f"t_end must be a positive number of seconds, got {t_end!r}")
    name, factory = get_model(model)
    t_wall0 = time.perf_counter()
    run = factory(room, mesh, dict(overrides or {}), **(model_options or {}))
    out = Path(out_dir)
    header = {
        "model": name,
        "geometry": geometry,
        "room": room.name if room is not None else None,
        "mesh": {"vertices": mesh.n_points, "triangles": mesh.n_triangles,
                 **(mesh_options or {})},
        "t_end": t_end,
        "parameters": run.parameters(),
    }
    warnings = list(getattr(run, "warnings", []))
    if warnings:
        header["warnings"] = warnings
        for w in warnings:
            print(f"pedmesh: warning: {w}", file=sys.stderr)
    writer = RunWriter(out, header, exit_names=mesh.exit_names,
                       outflow=hasattr(run, "outflow_rates"))
    tty = sys.stderr.isatty()
    bar = tqdm(total=round(t_end, 3), unit="s", disable=quiet, file=sys.stderr,
               dynamic_ncols=True, desc=f"{name}", leave=True,
               mininterval=0.5 if tty else 30.0,
               bar_format="{desc}: {percentage:3.0f}%|{bar}| t={n:.1f}/{total:.0f} s "
                          "[{elapsed}<{remaining}] {postfix}")
    next_sample = 0.0
    next_frame = 0.0
    frame = 0
    last_frame_t = -math.inf
    status = "finished"
    error = None

    def record() -> None:
        nonlocal next_sample, next_frame, frame, last_frame_t
        t = run.t
        if t >= next_sample - 1e-9:
            writer.sample(t, run.evacuated)
            if hasattr(run, "outflow_rates"):
                writer.outflow(t, run.outflow_rates())
            if hasattr(run, "flush_records"):
                run.flush_records(writer)
            next_sample += run.sample_interval * max(1, math.floor((t - next_sample) / run.sample_interval + 1e-9) + 1)
        if t >= next_frame - 1e-9:
            run.write_frame(writer, frame)
            frame += 1
            last_frame_t = t
            next_frame += run.output_interval * max(1, math.floor((t - next_frame) / run.output_interval + 1e-9) + 1)

    try:
        record()
        last_bar = 0.0
        while not run.done and run.t < t_end - 1e-9:
            run.step()
            record()
            if stop_requested():
                raise KeyboardInterrupt
            if run.t - last_bar >= 0.5 or run.done:
                bar.update(round(min(run.t, t_end) - last_bar, 3))
                last_bar = min(run.t, t_end)
                bar.set_postfix_str(f"inside {run.remaining:.0f}/{run.n_initial:.0f}", refresh=False)
        if not run.done:
            status = "stopped at t_end"
        # the final state
        if run.t > last_frame_t + 1e-9:
            writer.sample(run.t, run.evacuated)
            if hasattr(run, "outflow_rates"):
                writer.outflow(run.t, run.outflow_rates())
            if hasattr(run, "flush_records"):
                run.flush_records(writer)
            run.write_frame(writer, frame)
            frame += 1
        bar.update(round(min(run.t, t_end) - last_bar, 3))
        if run.done:
            bar.total = bar.n
    except KeyboardInterrupt:
        status = "interrupted"
    except SimulationError as exc:
        status = "failed"
        error = str(exc)
    finally:
        bar.close()
        summary = writer.finish(
            status=status, error=error, t_stop=run.t, frames=frame,
            wall_time_s=time.perf_counter() - t_wall0, **run.summary(),
        )
    if status == "interrupted":
        raise RunInterrupted(run.t, out)
    if status == "failed":
        raise SimulationError(f"{error} (results up to then are in {out})")
    return summary
