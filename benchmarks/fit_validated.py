"""Fit a few social-force parameters to the validation data (``benchmarks/validation.py``).

What is fixed
    ``preset=weidmann`` with ``speed_law=weidmann``, ``density_self=0`` and ``U_f=1.34``
    m/s: a lone walker walks at Weidmann's free speed by construction (checked at the end
    with the free-walking part). Every other parameter keeps its preset value (r = 0.15 m,
    R = 0.7 m, B = 0.08 m, k, kappa, m = 60 kg).

What is fitted (four parameters, bounds = the physically plausible range)
    ``gamma_w`` [1/m^2] in [1.5, 4.0] (Weidmann: 1.913), ``tau`` [s] in [0.3, 1.0] (Table 1:
    0.5), ``rho_jam`` [1/m^2] in [5, 10] (Weidmann: 5.4) and the repulsion strength ``A``
    [N] in [400, 3000] (Table 1: 2000). ``gamma_w`` and ``rho_jam`` shape the desired speed
    U_e(rho) = U_f (1 - exp(-gamma_w (1/rho - 1/rho_jam))) at the densities of the
    experiments; ``tau`` sets the driving force m U_f / tau against the repulsion, i.e. how
    hard a queue presses through a door, and ``A`` how strongly it is held apart. (The body
    radius r was left at 0.15 m: probes with r = 0.18 and 0.2 m raised the corridor-fed
    exit flow of uo-095, which is too high already.)

The corridor runs' entrance
    The corridor runs are fed with the experiment's own inflow (``validation.py --entrance
    replay``: each person enters at y = 7.5 m when they crossed it in the experiment). The
    experiment let its people in at a controlled rate from an unrecorded waiting area, so
    the entrance flow is the experiment's boundary condition, not something to predict; a
    first fit (``docs/validation/fit_evaluations_door.csv``) modelled it as a door with a
    waiting crowd and could not meet the narrow-entrance runs and uo-095's exit at once
    (``docs/validation/corridor_flows.md``).

Objective (a weighted sum of squares of relative errors, each divided by its tolerance)
    Measured by :func:`validation.run_validation` (parts ``corridor`` and ``bottleneck``,
    Voronoi samples from every frame) -- the same PedPy measurement for simulation and
    experiment; nothing of it is duplicated here::

        F = sum_runs (e_J / 0.10)^2                  5 corridor runs uo-*: exit flow J [1/s]
          + sum_b    (e_b / (0.3/1.9))^2            J/b at b = 0.8, 1.2, 1.8, 2.5 m vs 1.9 /(m s)
          + sum_rho  (e_v / 0.15)^2                 pooled Voronoi speed at rho = 1, 2, 3 /m^2
          + 100 * (runs that failed or did not empty the room within 600 s)

    with e = sim / reference - 1. A tolerance is the target's band: 10 % for the corridor
    flows, 1.6-2.2 /(m s) (= 1.9 +- 15.8 %) for the bottleneck, 15 % for the speeds, so a
    term is 1 on the edge of its band. A density bin the experiment fills but the
    simulation does not (no samples) counts as e_v = 0.5. A failed run's own term is
    dropped (its error is nan) and replaced by the penalty.

Method
    1. A coarse grid (3 x 2 x 2 x 3: gamma_w 1.9/2.2/2.5, tau 0.3/0.4, rho_jam 5/5.6,
       A 700/1000/1400 N, chosen from about 30 probes of single points: a weaker repulsion
       lowers the corridor-fed exit flow of uo-095 more than the bottleneck flows, and
       gamma_w near Weidmann's slows the corridor at 1.5 /m^2 as uo-145 needs), evaluated
       ``--jobs`` at a time in separate processes (each evaluation in its own temporary
       output directory, ``NUMBA_NUM_THREADS=1``).
    2. ``scipy.optimize.minimize(method="Nelder-Mead")`` with bounds, from the best grid
       point, in coordinates scaled to [0, 1] per parameter, an initial simplex of half a
       grid step along each axis (towards the interior), ``xatol`` 0.015 (1.5 % of each
       range) and at most ``--nm-evals`` (25) function calls.

    Parameters are rounded (gamma_w, rho_jam to 0.001, tau to 0.0001) before a run; every
    evaluation is printed (parameters, errors, objective, seconds) and appended to a CSV
    (``docs/validation/fit_evaluations.csv``) as soon as it ends. A rerun reads the CSV and
    skips every point already in it, so an interrupted fit loses nothing and Nelder-Mead,
    which is deterministic, replays its path to where it stopped.

Output
    ``pedmesh/data/validated.json`` (parameters including the fixed ones, objective, errors,
    fitted names, method, data, date, version) and ``docs/validation/fit.md`` (every target:
    simulation vs reference, pass/fail against its band, the free speed, the best points of
    the grid and of the optimizer). The full table of the fitted set then comes from::

        python benchmarks/validation.py --preset weidmann --param speed_law=weidmann \\
            --param density_self=0 --param U_f=1.34 --param gamma_w=... --param tau=... \\
            --param rho_jam=... --param A=... --entrance replay --bottleneck --free \\
            --out docs/validation/validated

Usage::

    NUMBA_NUM_THREADS=1 python benchmarks/fit_validated.py [--jobs 2] [--nm-evals 25]
        [--csv PATH] [--data DIR] [--grid-only] [--report-only]

Data: Jülich uni-directional corridor runs uo-* (Pedestrian Dynamics Data Archive,
Forschungszentrum Jülich; Zhang et al., J. Stat. Mech. P06004, 2011), the bottleneck
specific flow ~1.9 /(m s) of Seyfried et al. 2009 / Liddle et al. 2011, Weidmann's free
speed 1.34 m/s.
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")  # before numba is imported anywhere

import argparse
import concurrent.futures as cf
import csv
import datetime
import itertools
import json
import math
import multiprocessing
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

PRESET = "weidmann"
FIXED: dict[str, Any] = {"speed_law": "weidmann", "density_self": 0, "U_f": 1.34}
#: fitted parameters: (lower, upper) bound, rounding (decimals), grid levels
FIT: dict[str, dict[str, Any]] = {
    "gamma_w": {"bounds": (1.5, 4.0), "decimals": 3, "grid": (1.9, 2.2, 2.5)},
    "tau": {"bounds": (0.3, 1.0), "decimals": 4, "grid": (0.3, 0.4)},
    "rho_jam": {"bounds": (5.0, 10.0), "decimals": 3, "grid": (5.0, 5.6)},
    "A": {"bounds": (400.0, 3000.0), "decimals": 0, "grid": (700.0, 1000.0, 1400.0)},
}
NAMES = tuple(FIT)
PARTS = ("corridor", "bottleneck")
#: the corridor runs' entrance (benchmarks/validation.py): the experiment's own inflow
ENTRANCE = "replay"

CORRIDOR_RUNS = ("uo-070-180-180", "uo-100-180-180", "uo-145-180-180", "uo-180-180-180",
                 "uo-180-180-095")
WIDTHS = (0.8, 1.2, 1.8, 2.5)  # [m]
FD_RHOS = (1.0, 2.0, 3.0)  # [1/m^2]
BOTTLENECK_REF = 1.9  # [1/(m s)]
BOTTLENECK_BAND = (1.6, 2.2)  # [1/(m s)]
TOL_CORRIDOR = 0.10
TOL_BOTTLENECK = 0.3 / BOTTLENECK_REF
TOL_FD = 0.15
MISSING_FD_ERROR = 0.5
PENALTY = 100.0
FREE_TOL = 0.05  # check of the free speed (not fitted): within 5 % of 1.34 m/s

DEFAULT_CSV = ROOT / "docs" / "validation" / "fit_evaluations.csv"
OUT_JSON = ROOT / "pedmesh" / "data" / "validated.json"
OUT_MD = ROOT / "docs" / "validation" / "fit.md"
FIXED_KEY = json.dumps({"preset": PRESET, **FIXED, "parts": list(PARTS),
                        "entrance": ENTRANCE}, sort_keys=True)

# CSV columns: the fitted parameters, then the simulated values and relative errors
SIM_COLS = ([f"J_exit_sim/{r}" for r in CORRIDOR_RUNS]
            + [f"Jb_sim/b={b:g}" for b in WIDTHS]
            + [f"v_sim/rho={d:g}" for d in FD_RHOS] + [f"n_sim/rho={d:g}" for d in FD_RHOS])
ERR_COLS = ([f"err/corridor/{r}/J_exit" for r in CORRIDOR_RUNS]
            + [f"err/bottleneck/b={b:g}" for b in WIDTHS]
            + [f"err/fd/rho={d:g}" for d in FD_RHOS])
REF_COLS = [f"J_exit_exp/{r}" for r in CORRIDOR_RUNS] + [f"v_exp/rho={d:g}" for d in FD_RHOS]
COLUMNS = (["eval", "phase", *NAMES, "objective", "failed", "clogged", "seconds", "rms_all",
            "date", "fixed"] + SIM_COLS + ERR_COLS + REF_COLS)


# --------------------------------------------------------------------------- evaluation
def rounded(x: dict[str, float]) -> dict[str, float]:
    """The parameter point rounded as it is run (and as the CSV keys it)."""
    return {n: round(float(x[n]), FIT[n]["decimals"]) for n in NAMES}


def key_of(x: dict[str, float]) -> tuple[float, ...]:
    r = rounded(x)
    return tuple(r[n] for n in NAMES)


def evaluate(x: dict[str, float], data_dir: str | None = None,
             keep_dir: str | None = None) -> dict[str, Any]:
    """One evaluation (runs in a worker process or in-process): :func:`run_validation`
    of the corridor and bottleneck parts at ``FIXED`` + ``x``; a flat record of the
    simulated values, the references and the relative errors (no objective)."""
    warnings.filterwarnings("ignore")
    from validation import run_validation

    x = rounded(x)
    t0 = time.perf_counter()
    res = run_validation({**FIXED, **x}, PRESET, parts=PARTS, data_dir=data_dir,
                         out_dir=keep_dir, fd_frames="all", entrance=ENTRANCE,
                         log=lambda *a, **k: None)
    rec: dict[str, Any] = dict(x)
    failed = clogged = 0
    rows = {r["run"]: r for r in res["corridor"]["rows"]}
    for name in CORRIDOR_RUNS:
        row = rows.get(name)
        if row is None:
            raise RuntimeError(f"experiment {name} missing from the data directory")
        failed += row["error"] is not None
        clogged += row["error"] is None and row["status"] != "finished"
        rec[f"J_exit_sim/{name}"] = row["J_exit_sim"]
        rec[f"J_exit_exp/{name}"] = row["J_exit_exp"]
        rec[f"err/corridor/{name}/J_exit"] = row["J_exit_err"]
    for row in res["bottleneck"]:
        b = row["width_m"]
        failed += row["error"] is not None
        clogged += row["error"] is None and row["status"] != "finished"
        rec[f"Jb_sim/b={b:g}"] = row["J_per_b"]
        rec[f"err/bottleneck/b={b:g}"] = row["err"]
    for fd in res["corridor"]["fd"]:
        d = fd["density"]
        rec[f"v_sim/rho={d:g}"] = fd["speed_sim"]
        rec[f"n_sim/rho={d:g}"] = fd["n_sim"]
        rec[f"v_exp/rho={d:g}"] = fd["speed_exp"] if fd["n_exp"] else math.nan
        rec[f"err/fd/rho={d:g}"] = (fd["speed_sim"] / fd["speed_exp"] - 1.0
                                    if fd["n_exp"] and fd["n_sim"] else math.nan)
    rec["failed"], rec["clogged"] = failed, clogged
    rec["rms_all"] = res["errors"]["rms"]
    rec["seconds"] = time.perf_counter() - t0
    return rec


def objective(rec: dict[str, Any]) -> float:
    """The weighted sum of squares of the module docstring."""
    f = 0.0
    for r in CORRIDOR_RUNS:
        e = float(rec[f"err/corridor/{r}/J_exit"])
        f += (e / TOL_CORRIDOR) ** 2 if math.isfinite(e) else 0.0
    for b in WIDTHS:
        e = float(rec[f"err/bottleneck/b={b:g}"])
        f += (e / TOL_BOTTLENECK) ** 2 if math.isfinite(e) else 0.0
    for d in FD_RHOS:
        if not math.isfinite(float(rec[f"v_exp/rho={d:g}"])):
            continue  # the experiment has no samples at this density: no target
        e = float(rec[f"err/fd/rho={d:g}"])
        f += ((e if math.isfinite(e) else MISSING_FD_ERROR) / TOL_FD) ** 2
    return f + PENALTY * (float(rec["failed"]) + float(rec["clogged"]))


# --------------------------------------------------------------------------- the CSV
class Log:
    """The evaluations so far (read from and appended to the CSV)."""

    def __init__(self, path: Path):
        self.path = path
        self.rows: dict[tuple[float, ...], dict[str, Any]] = {}
        self.order: list[dict[str, Any]] = []
        if path.is_file():
            with path.open(newline="") as fh:
                for row in csv.DictReader(fh):
                    if row.get("fixed") != FIXED_KEY:
                        continue
                    rec = {k: _num(v) for k, v in row.items()}
                    rec["fixed"], rec["phase"], rec["date"] = row["fixed"], row["phase"], \
                        row["date"]
                    k = key_of(rec)
                    if k not in self.rows:
                        self.rows[k] = rec
                        self.order.append(rec)
        self.resumed = len(self.order)

    def get(self, x) -> dict[str, Any] | None:
        return self.rows.get(key_of(x))

    def add(self, rec: dict[str, Any], phase: str) -> dict[str, Any]:
        rec = dict(rec)
        rec["eval"] = len(self.order) + 1
        rec["phase"] = phase
        rec["objective"] = objective(rec)
        rec["date"] = datetime.datetime.now().isoformat(timespec="seconds")
        rec["fixed"] = FIXED_KEY
        self.rows[key_of(rec)] = rec
        self.order.append(rec)
        new = not self.path.is_file()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with self.path.open("a", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=COLUMNS, extrasaction="ignore")
            if new:
                w.writeheader()
            w.writerow({k: _fmt(rec.get(k)) for k in COLUMNS})
        print(line_of(rec), flush=True)
        return rec

    def best(self) -> dict[str, Any]:
        return min(self.order, key=lambda r: (r["objective"], r["eval"]))


def _num(v: str):
    try:
        return float(v)
    except (TypeError, ValueError):
        return v


def _fmt(v):
    if isinstance(v, float):
        return "nan" if not math.isfinite(v) else repr(round(v, 6))
    return "" if v is None else v


def line_of(rec: dict[str, Any]) -> str:
    """One printed line per evaluation."""
    p = " ".join(f"{n}={rec[n]:g}" for n in NAMES)
    c = " ".join(_pc(rec[f"err/corridor/{r}/J_exit"]) for r in CORRIDOR_RUNS)
    b = " ".join(f"{float(rec[f'Jb_sim/b={w:g}']):.2f}" for w in WIDTHS)
    v = " ".join(_pc(rec[f"err/fd/rho={d:g}"]) for d in FD_RHOS)
    extra = ""
    if rec["failed"] or rec["clogged"]:
        extra = f" failed {rec['failed']:.0f} clogged {rec['clogged']:.0f}"
    return (f"[{rec['phase']} #{rec['eval']:.0f}] {p} | J_exit {c} | J/b {b} | v(rho) {v}"
            f" | F = {rec['objective']:.2f}{extra} | {rec['seconds']:.0f} s")


def _pc(e) -> str:
    e = float(e)
    return f"{100 * e:+.0f}%" if math.isfinite(e) else "nan"


# --------------------------------------------------------------------------- the fit
def grid_points() -> list[dict[str, float]]:
    return [dict(zip(NAMES, p)) for p in itertools.product(*(FIT[n]["grid"] for n in NAMES))]


def run_grid(log: Log, jobs: int, data_dir: str | None) -> None:
    todo = [x for x in grid_points() if log.get(x) is None]
    print(f"grid: {len(grid_points())} points, {len(grid_points()) - len(todo)} already in "
          f"{log.path}, {len(todo)} to run with {jobs} process(es)", flush=True)
    if not todo:
        return
    if jobs <= 1:
        for x in todo:
            log.add(evaluate(x, data_dir), "grid")
        return
    ctx = multiprocessing.get_context("spawn")  # fresh interpreters: NUMBA_NUM_THREADS holds
    with cf.ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
        futures = {pool.submit(evaluate, x, data_dir): x for x in todo}
        for fut in cf.as_completed(futures):
            try:
                log.add(fut.result(), "grid")
            except Exception as exc:  # noqa: BLE001 -- one bad point must not end the fit
                print(f"grid point {futures[fut]} raised {type(exc).__name__}: {exc}",
                      flush=True)


def _to_x(z: np.ndarray) -> dict[str, float]:
    return {n: FIT[n]["bounds"][0] + float(np.clip(zi, 0.0, 1.0))
            * (FIT[n]["bounds"][1] - FIT[n]["bounds"][0]) for n, zi in zip(NAMES, z)}


def _to_z(x: dict[str, float]) -> np.ndarray:
    return np.array([(x[n] - FIT[n]["bounds"][0]) / (FIT[n]["bounds"][1] - FIT[n]["bounds"][0])
                     for n in NAMES])


def run_nelder_mead(log: Log, max_evals: int, data_dir: str | None) -> Any:
    from scipy.optimize import minimize

    start = log.best()
    z0 = _to_z(start)
    simplex = [z0]
    for i, n in enumerate(NAMES):
        g = FIT[n]["grid"]
        lo, hi = FIT[n]["bounds"]
        step = 0.5 * (g[1] - g[0]) / (hi - lo)
        z = z0.copy()
        z[i] = z0[i] + step if z0[i] + step <= 1.0 else z0[i] - step
        simplex.append(z)
    calls = {"n": 0, "new": 0}

    def f(z: np.ndarray) -> float:
        calls["n"] += 1
        x = _to_x(z)
        rec = log.get(x)
        if rec is None:
            try:
                rec = log.add(evaluate(x, data_dir), "nm")
            except Exception as exc:  # noqa: BLE001
                print(f"point {rounded(x)} raised {type(exc).__name__}: {exc}", flush=True)
                return 10 * PENALTY
            calls["new"] += 1
        else:
            print(f"[nm] {' '.join(f'{n}={v:g}' for n, v in rounded(x).items())}: "
                  f"F = {rec['objective']:.2f} (from the CSV, eval #{rec['eval']:.0f})",
                  flush=True)
        return float(rec["objective"])

    print(f"Nelder-Mead from eval #{start['eval']:.0f} (F = {start['objective']:.2f}), at most "
          f"{max_evals} calls", flush=True)
    res = minimize(f, z0, method="Nelder-Mead", bounds=[(0.0, 1.0)] * len(NAMES),
                   options={"initial_simplex": np.array(simplex), "maxfev": max_evals,
                            "xatol": 0.015, "fatol": 0.05})
    print(f"Nelder-Mead: {res.message} ({calls['n']} calls, {calls['new']} new runs; best "
          f"{rounded(_to_x(res.x))}, F = {res.fun:.2f})", flush=True)
    return res


# --------------------------------------------------------------------------- report
def free_check(x: dict[str, float], data_dir: str | None) -> dict[str, Any]:
    """The free-walking part at the fitted point (a lone walker's mean speed)."""
    warnings.filterwarnings("ignore")
    from validation import run_validation

    res = run_validation({**FIXED, **rounded(x)}, PRESET, parts=("free",), data_dir=data_dir,
                         log=lambda *a, **k: None)
    return res["free"]


def targets(rec: dict[str, Any], free: dict[str, Any] | None) -> list[dict[str, Any]]:
    """Every target of the fit: name, simulation, reference, error, band, pass."""
    out = []
    for r in CORRIDOR_RUNS:
        sim, ref = float(rec[f"J_exit_sim/{r}"]), float(rec[f"J_exit_exp/{r}"])
        e = float(rec[f"err/corridor/{r}/J_exit"])
        out.append({"key": f"corridor/{r}/J_exit", "target": f"{r}: exit flow J [1/s]",
                    "sim": sim, "ref": ref, "err": e,
                    "band": "within 10 %", "pass": math.isfinite(e) and abs(e) <= TOL_CORRIDOR})
    for b in WIDTHS:
        sim = float(rec[f"Jb_sim/b={b:g}"])
        out.append({"key": f"bottleneck/b={b:g}",
                    "target": f"bottleneck b = {b:g} m: J/b [1/(m s)]", "sim": sim,
                    "ref": BOTTLENECK_REF, "err": float(rec[f"err/bottleneck/b={b:g}"]),
                    "band": f"{BOTTLENECK_BAND[0]:g}-{BOTTLENECK_BAND[1]:g}",
                    "pass": math.isfinite(sim)
                    and BOTTLENECK_BAND[0] <= sim <= BOTTLENECK_BAND[1]})
    for d in FD_RHOS:
        ref = float(rec[f"v_exp/rho={d:g}"])
        if not math.isfinite(ref):
            continue
        e = float(rec[f"err/fd/rho={d:g}"])
        out.append({"key": f"fd/rho={d:g}",
                    "target": (f"Voronoi speed at {d:g} /m^2 [m/s] (n sim = "
                               f"{float(rec[f'n_sim/rho={d:g}']):.0f})"),
                    "sim": float(rec[f"v_sim/rho={d:g}"]), "ref": ref, "err": e,
                    "band": "within 15 %", "pass": math.isfinite(e) and abs(e) <= TOL_FD})
    if free is not None:
        out.append({"key": "free/speed", "target": "free walking speed [m/s] (fixed U_f, check)",
                    "sim": free["speed"], "ref": 1.34, "err": free["err"],
                    "band": "within 5 % (check)",
                    "pass": math.isfinite(free["err"]) and abs(free["err"]) <= FREE_TOL})
    return out


def _elapsed(log: Log) -> float:
    """Wall time [s] from the start of the first evaluation in the CSV to the end of the
    last (by their recorded end times and durations)."""
    ends = [datetime.datetime.fromisoformat(r["date"]) for r in log.order]
    start = min(e - datetime.timedelta(seconds=float(r["seconds"]))
                for e, r in zip(ends, log.order))
    return (max(ends) - start).total_seconds()


def noise_note(log: Log, radius: float = 0.05) -> str:
    """How much the objective scatters among the evaluated points near the best one
    (within ``radius`` in the scaled coordinates): each point is one realisation of a
    chaotic crowd, so differences of this size are not significant."""
    best = log.best()
    zb = _to_z(best)
    near = [r for r in log.order if np.max(np.abs(_to_z(r) - zb)) <= radius]
    fs = [float(r["objective"]) for r in near]
    return (f"Noise: the {len(near)} evaluated points within {100 * radius:g} % of each range "
            f"of the best one have F = {min(fs):.2f}-{max(fs):.2f}; differences of this size "
            f"between nearby points are scatter (a run is reproducible, but a tiny change of "
            f"a parameter gives another realisation of a chaotic crowd), not signal.")


def best_grid_note(grid: list[dict[str, Any]]) -> str:
    """The best grid point (the start of Nelder-Mead) in one line."""
    if not grid:
        return "No grid evaluations."
    g = min(grid, key=lambda r: (r["objective"], r["eval"]))
    worst = max(float(r["objective"]) for r in grid)
    return (f"Best grid point: #{g['eval']:.0f} " + " ".join(f"{n}={g[n]:g}" for n in NAMES)
            + f", F = {g['objective']:.2f} (the grid's F ranged up to {worst:.2f}).")


def _r4(v):
    v = float(v)
    return round(v, 4) if math.isfinite(v) else None


def _f(v, fmt=".2f"):
    v = float(v)
    return format(v, fmt) if math.isfinite(v) else "-"


def write_outputs(log: Log, nm: Any, free: dict[str, Any], wall_s: float) -> dict[str, Any]:
    import pedmesh

    best = log.best()
    x = rounded(best)
    tg = targets(best, free)
    errors = {f"corridor/{r}/J_exit": best[f"err/corridor/{r}/J_exit"] for r in CORRIDOR_RUNS}
    errors.update({f"bottleneck/b={b:g}": best[f"err/bottleneck/b={b:g}"] for b in WIDTHS})
    errors.update({f"fd/rho={d:g}": best[f"err/fd/rho={d:g}"] for d in FD_RHOS
                   if math.isfinite(float(best[f"v_exp/rho={d:g}"]))})
    errors["free/speed"] = free["err"]
    errors = {k: (round(float(v), 4) if math.isfinite(float(v)) else None)
              for k, v in errors.items()}
    grid = [r for r in log.order if r["phase"] == "grid"]
    nmr = [r for r in log.order if r["phase"] == "nm"]
    method = (
        f"Weighted least squares of relative errors (each over its tolerance: corridor exit "
        f"flows 10 %, bottleneck J/b 0.3/1.9, Voronoi speeds at 1/2/3 /m^2 15 %; +{PENALTY:g} "
        f"per failed or clogged run), measured by benchmarks/validation.py run_validation "
        f"(corridor with the experiment's inflow, entrance={ENTRANCE}, + bottleneck, "
        f"fd_frames=all). Coarse grid {len(grid)} points ("
        + ", ".join(f"{n} {FIT[n]['grid']}" for n in NAMES)
        + "), then bounded Nelder-Mead from the best grid point "
        f"(scaled coordinates, xatol 1.5 % of each range, {len(nmr)} new runs); "
        f"benchmarks/fit_validated.py, evaluations in docs/validation/fit_evaluations.csv")
    out = {
        "parameters": {"preset": PRESET, **FIXED, **x},
        "objective": round(float(best["objective"]), 4),
        "errors": errors,
        "targets": {t["key"]: {"sim": _r4(t["sim"]), "ref": _r4(t["ref"]), "band": t["band"],
                               "pass": bool(t["pass"])} for t in tg},
        "fitted": list(NAMES),
        "bounds": {n: list(FIT[n]["bounds"]) for n in NAMES},
        "method": method,
        "data": "Juelich uo-* runs; Seyfried 2009/Liddle 2011 bottleneck ~1.9 /(m s); "
                "Weidmann free speed 1.34",
        "date": datetime.date.today().isoformat(),
        "pedmesh_version": pedmesh.__version__,
    }
    OUT_JSON.parent.mkdir(parents=True, exist_ok=True)
    OUT_JSON.write_text(json.dumps(out, indent=1) + "\n")

    params = " ".join(f"--param {k}={v}" for k, v in {**FIXED, **x}.items())
    bounds_txt = ", ".join(f"{n} {FIT[n]['bounds']}" for n in NAMES)
    md = ["# SFM parameters fitted to the validation data", "",
          "Written by `benchmarks/fit_validated.py` (the objective and the method are in its "
          "docstring); values in `pedmesh/data/validated.json`, every evaluation in "
          "`docs/validation/fit_evaluations.csv`, the full validation table of the fitted set "
          "in `validated/validation.md`.", "",
          f"Preset `{PRESET}` with fixed {', '.join(f'`{k}={v}`' for k, v in FIXED.items())}; "
          f"fitted: {', '.join(f'`{n}` = {x[n]:g}' for n in NAMES)} "
          f"(bounds {bounds_txt}). "
          f"Objective F = {best['objective']:.2f} (eval #{best['eval']:.0f}, {best['phase']}).",
          "", "## Targets", "",
          "| target | simulation | reference | error | band | pass |", "|---|---|---|---|---|---|"]
    for t in tg:
        md.append(f"| {t['target']} | {_f(t['sim'])} | {_f(t['ref'])} | {_pc(t['err'])} | "
                  f"{t['band']} | {'pass' if t['pass'] else '**fail**'} |")
    npass = sum(t["pass"] for t in tg)
    md += ["", f"{npass} of {len(tg)} targets pass.", ""]
    missed = [t for t in tg if not t["pass"]]
    if missed:
        md.append("Missed: " + "; ".join(f"{t['target']} {_f(t['sim'])} vs {_f(t['ref'])} "
                                         f"({_pc(t['err'])}, band {t['band']})" for t in missed)
                  + ".")
        md.append("")
    md += ["## History", "",
           f"{len(grid)} grid evaluations, {len(nmr)} Nelder-Mead runs"
           + (f" ({nm.message.strip().rstrip('.')}, {nm.nfev} calls)" if nm is not None else "")
           + f"; sum of evaluation times {sum(float(r['seconds']) for r in log.order):.0f} s; "
           f"{_elapsed(log) / 60:.1f} min from the start of the first evaluation to the end of "
           f"the last (this invocation: {wall_s / 60:.1f} min).", "",
           noise_note(log), "", best_grid_note(grid), "",
           "Best points (F: objective; errors in %):", "",
           "| # | phase | " + " | ".join(NAMES) + " | F | J_exit 070/100/145/180/095 | "
           "J/b 0.8/1.2/1.8/2.5 | v at 1/2/3 /m^2 | s |",
           "|---|---|" + "---|" * len(NAMES) + "---|---|---|---|---|"]
    for r in sorted(log.order, key=lambda r: r["objective"])[:8]:
        md.append(f"| {r['eval']:.0f} | {r['phase']} | "
                  + " | ".join(f"{r[n]:g}" for n in NAMES) + f" | {r['objective']:.2f} | "
                  + " ".join(_pc(r[f"err/corridor/{c}/J_exit"]) for c in CORRIDOR_RUNS) + " | "
                  + " ".join(_f(r[f"Jb_sim/b={b:g}"]) for b in WIDTHS) + " | "
                  + " ".join(_pc(r[f"err/fd/rho={d:g}"]) for d in FD_RHOS)
                  + f" | {float(r['seconds']):.0f} |")
    md += ["", "Full table of the fitted set:", "", "```",
           f"python benchmarks/validation.py --preset {PRESET} {params} --entrance "
           f"{ENTRANCE} --bottleneck --free --out docs/validation/validated", "```", ""]
    OUT_MD.parent.mkdir(parents=True, exist_ok=True)
    OUT_MD.write_text("\n".join(md))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--jobs", type=int, default=1, help="grid evaluations at once (processes)")
    ap.add_argument("--nm-evals", type=int, default=25,
                    help="most Nelder-Mead function calls (default 25)")
    ap.add_argument("--csv", type=Path, default=DEFAULT_CSV, help="evaluation log (resumed)")
    ap.add_argument("--data", default=None, metavar="DIR", help="experiments directory")
    ap.add_argument("--grid-only", action="store_true", help="stop after the grid")
    ap.add_argument("--report-only", action="store_true",
                    help="no new runs but the free check: report the best point of the CSV")
    args = ap.parse_args(argv)
    warnings.filterwarnings("ignore")
    t0 = time.perf_counter()
    log = Log(args.csv)
    print(f"{log.resumed} evaluations read from {args.csv}", flush=True)
    nm = None
    if not args.report_only:
        run_grid(log, max(1, args.jobs), args.data)
        if not log.order:
            raise SystemExit("no evaluation succeeded")
        if not args.grid_only and args.nm_evals > 0:
            nm = run_nelder_mead(log, args.nm_evals, args.data)
    best = log.best()
    free = free_check(best, args.data)
    out = write_outputs(log, nm, free, time.perf_counter() - t0)
    print(f"\nbest: {out['parameters']}  F = {out['objective']}")
    print(f"free speed {free['speed']:.3f} m/s ({_pc(free['err'])})")
    print(f"wrote {OUT_JSON} and {OUT_MD}; wall time {(time.perf_counter() - t0) / 60:.1f} min")
    return 0


if __name__ == "__main__":
    sys.exit(main())
