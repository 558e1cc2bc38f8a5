"""An ensemble's results (see :mod:`pedmesh.ensembles`): ``ensemble.csv``, the
statistics of T50/T90/T100 per sweep point in ``ensemble.json``, and the evacuation bands
of ``evacuation_bands.png``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import PedmeshError
from ..run.results import FINISHED_STATUSES
from .plan import TIMES
from ..io import run_folder as F


def percentile_stats(values: Sequence[float]) -> dict[str, float | None]:
    """The 5/50/95 percentiles, mean, standard deviation and count of the finite numbers
    in ``values`` (None where there are too few of them)."""
    v = np.asarray([x for x in values if x is not None and np.isfinite(x)], float)
    if len(v) == 0:
        return {"p5": None, "p50": None, "p95": None, "mean": None, "std": None, "n": 0}
    p5, p50, p95 = np.percentile(v, [5, 50, 95])
    return {"p5": float(p5), "p50": float(p50), "p95": float(p95), "mean": float(v.mean()),
            "std": float(v.std(ddof=1)) if len(v) > 1 else None, "n": int(len(v))}


def write_csv(path: Path, frame) -> None:
    """Write the DataFrame ``frame`` to the CSV file ``path`` in one atomic step."""
    F.atomic_write(path, frame.to_csv(index=False))


def _summaries(out: Path, frame, sweep: dict, meta: dict) -> dict:
    points = []
    for p, grp in frame.groupby("point", sort=True):
        done = grp[grp["status"].isin(FINISHED_STATUSES)]
        entry = {"point": int(p), "values": {k: grp.iloc[0][k] for k in sweep},
                 "members": int(len(grp)), "finished": int(len(done)),
                 "failed": int((grp["status"] == "failed").sum())}
        for k in TIMES:
            entry[k] = percentile_stats(list(done[k]))
        points.append(entry)
    data = {**meta, "points": points}

    F.atomic_write(out / F.ENSEMBLE_JSON, json.dumps(F.json_safe(data), indent=2) + "\n")
    return data


def evacuation_band(curves: Sequence[tuple[np.ndarray, np.ndarray]]):
    """``(t, lo, median, hi)`` of evacuation curves ``(t, n)`` (``t`` increasing, not
    empty): on 600 times from 0 to the last end, the 5th percentile, median and 95th
    percentile over the curves of the pedestrians out."""
    t_max = max(float(t[-1]) for t, _ in curves)
    grid = np.linspace(0.0, t_max, 600)
    n = np.array([np.interp(grid, t, e) for t, e in curves])
    lo, med, hi = np.percentile(n, [5, 50, 95], axis=0)
    return grid, lo, med, hi


def _bands(out: Path, frame, sweep: dict) -> Path | None:
    """evacuation_bands.png: median evacuation curve and 5-95 % band per sweep point."""
    from ..plotting import _plt
    from ..run.results import RunResult

    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    drawn = False
    for p, grp in frame.groupby("point", sort=True):
        curves = []
        for mid, status in zip(grp["member"], grp["status"]):
            if status not in FINISHED_STATUSES:
                continue
            try:
                curves.append(RunResult.load(out / F.ENSEMBLE_MEMBERS / mid).evacuation)
            except (PedmeshError, OSError, ValueError):
                continue
        if not curves:
            continue
        grid, lo, med, hi = evacuation_band(curves)
        vals = {k: grp.iloc[0][k] for k in sweep}
        label = ", ".join(f"{k}={v:g}" if isinstance(v, (int, float)) else f"{k}={v}"
                          for k, v in vals.items()) or "all members"
        line, = ax.plot(grid, med, label=f"{label} ({len(curves)} runs)")
        ax.fill_between(grid, lo, hi, color=line.get_color(), alpha=0.25, lw=0)
        drawn = True
    if not drawn:
        plt.close(fig)
        return None
    ax.set_xlabel("t [s]")
    ax.set_ylabel("pedestrians out")
    ax.set_title("evacuation: median and 5-95 % band over the members")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = out / "evacuation_bands.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def finish(out: Path, result, sweep: dict, meta: dict):
    """Write the final ensemble.csv, ensemble.json and evacuation_bands.png of the members'
    DataFrame ``result`` to ``out``, and return ``result``."""
    write_csv(out / F.ENSEMBLE_CSV, result)
    _summaries(out, result, sweep, meta)
    _bands(out, result, sweep)
    return result
