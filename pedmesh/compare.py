"""Comparing models on one room: run each (reusing finished runs), then plots and tables.

Model specifications are ``name`` or ``name:param=value:param=value`` (e.g. ``pw:c0=0.5``);
each runs into ``<out>/<label>/`` with the shared output contract, where the label is the
specification with ``:`` and ``=`` made file-name safe. The first model is the reference
the distances are measured against (normally ``sfm``).
"""

from __future__ import annotations

import csv
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from .analysis import (
    curve_distance,
    density_flow_diagram,
    density_l1,
    evacuation_times_from_curve,
    reference_flow,
)
from .errors import ParameterError, PedmeshError
from .parameters import DEFAULT_T_END_S
from .io import run_folder as F
from .run.results import RunResult

__all__ = ["ModelSpec", "parse_model_specs", "run_comparison", "ComparisonResult"]


@dataclass(frozen=True)
class ModelSpec:
    """A model name with parameter overrides and a label."""

    name: str
    overrides: dict = field(default_factory=dict)

    @property
    def label(self) -> str:
        if not self.overrides:
            return self.name
        return self.name + "_" + "_".join(f"{k}{v:g}" if isinstance(v, float) else f"{k}{v}"
                                          for k, v in self.overrides.items())


def parse_model_specs(text: str | Sequence[str]) -> list[ModelSpec]:
    """``"sfm,mac1,pw:c0=0.5"`` -> specs. Parameters after ``:`` are ``NAME=VALUE``."""
    from .models import get_model
    from .parameters import parse_overrides

    items = [s.strip() for s in (text.split(",") if isinstance(text, str) else text) if s.strip()]
    if not items:
        raise ParameterError("no models given (e.g. --models sfm,mac1,rdue)")
    out = []
    for it in items:
        name, *params = it.split(":")
        canon = get_model(name.strip()).name
        out.append(ModelSpec(canon, parse_overrides(params)))
    labels = [s.label for s in out]
    for lab in labels:
        if labels.count(lab) > 1:
            raise ParameterError(f"model '{lab}' is given twice")
    return out


def _settings_difference(res: RunResult, wanted: dict) -> str | None:
    """Why the run ``res`` cannot stand for a run with settings ``wanted`` (None if it can):
    an unfinished run or any recorded setting that differs."""
    if not res.finished:
        return f"its status is '{res.status}'"
    if not res.settings:
        return "it records no settings (made by an older pedmesh)"
    for k, there, asked in res.settings_differences(wanted)[:1]:
        return f"{k} differs ({there!r} there, {asked!r} asked)"
    return None


@dataclass
class ComparisonResult:
    """Runs of a comparison, the table rows written to comparison.csv and the binned
    density-flow diagrams (by run label; empty without plots)."""

    runs: dict
    rows: list
    out_dir: Path
    diagrams: dict = field(default_factory=dict)


def _density_or_none(res: RunResult, t: float, mesh):
    """Cell densities of a run's frame nearest time ``t`` [s], or None if it saved none (a
    broken frame is an error naming it)."""
    if not res.density_frames:
        return None
    return res.density_at(t, mesh)[1]


def _outflow_total(res: RunResult, kernel: bool = False, window: float = 2.0):
    """(t, total exit flow [ped/s]): the people out in the centred ``window`` [s] around
    each sample of the evacuation curve, divided by its length; the same for particle and
    continuum runs. With ``kernel`` (particle runs): the paper's f_c from the kernel fields
    at the exits (outflow_kernel.csv), which sees only the pedestrians still inside (those
    who crossed are removed) and so reads about half the crossing rate."""
    if kernel:
        if not res.has_table(F.OUTFLOW_KERNEL):
            return None
        t, flows, _ = res.outflow_kernel
        return t, flows.sum(axis=1)
    t, n = res.evacuation
    if len(t) < 2:
        return None
    lo = np.interp(t - 0.5 * window, t, n, left=0.0)
    hi = np.interp(t + 0.5 * window, t, n)
    return t, (hi - lo) / window


def _fd_samples(res: RunResult, mesh, every: float = 1.0):
    """(density, flow) of every cell in every frame at least ``every`` seconds apart."""
    rho_s, flow_s = [], []
    last = -math.inf
    for t, _ in res.density_frames:
        if t - last < every - 1e-9 or t <= 0:
            continue
        last = t
        _, rho, vel = res.density_at(t, mesh)
        rho_s.append(rho)
        flow_s.append(rho * np.hypot(vel[:, 0], vel[:, 1]))
    if not rho_s:
        return np.zeros(0), np.zeros(0)
    return np.concatenate(rho_s), np.concatenate(flow_s)


def run_comparison(room, mesh, specs: Sequence[ModelSpec], out_dir: str | Path, *,
                   t_end: float = DEFAULT_T_END_S, quiet: bool = False, geometry: str | None = None,
                   mesh_options: dict | None = None, density_times: Sequence[float] | None = None,
                   reuse: bool = True, plots: bool = True,
                   preset: str | None = None,
                   max_people: int | None = None) -> ComparisonResult:
    """Run (or reuse) every model, then write plots, comparison.csv and comparison.md.
    ``preset``: the parameter preset of every run (:mod:`pedmesh.presets`; None: the room
    file's, else the default); ``max_people``: the largest crowd a run takes."""
    from .presets import resolve_preset
    from .run import run_model
    from .run.driver import run_settings

    preset = resolve_preset(preset, room)

    out = Path(out_dir)
    _check_compare_folder(out, [s.label for s in specs])
    out.mkdir(parents=True, exist_ok=True)
    mesh_options = dict(mesh_options or {})
    runs: dict[str, RunResult] = {}
    for k, spec in enumerate(specs):
        d = out / spec.label
        prefix = f"[{k + 1}/{len(specs)}] {spec.label}"
        wanted = run_settings(spec.name, overrides=spec.overrides, t_end=t_end,
                              geometry=geometry, mesh_options=mesh_options, preset=preset)
        why = "no run there yet"
        if F.has_summary(d):
            try:
                res = RunResult.load(d)
            except PedmeshError as exc:  # a broken summary: run it again
                res, why = None, f"its summary is broken: {exc}"
            else:
                why = _settings_difference(res, wanted) if reuse else "reuse is off"
            if why is None:
                if not quiet:
                    print(f"{prefix}: reusing the finished run in {d}", file=sys.stderr)
                runs[spec.label] = res
                continue
        if not quiet:
            print(f"{prefix}: running ({why})", file=sys.stderr)
        run_model(room, mesh, spec.name, overrides=spec.overrides, t_end=t_end, out_dir=d,
                  quiet=quiet, geometry=geometry, mesh_options=mesh_options, preset=preset,
                  max_people=max_people)
        runs[spec.label] = RunResult.load(d)
    labels = list(runs)
    ref = runs[labels[0]]
    n0 = float(ref.summary["n_initial"])
    if density_times is None:
        t90 = ref.summary.get("t_evac_90") or float(ref.evacuation[0][-1])
        density_times = [round(f * t90) for f in (0.25, 0.5, 0.75)]
    ref_flow = _outflow_total(ref)
    ref_rho = {tt: _density_or_none(ref, tt, mesh) for tt in density_times}
    rows = []
    for lab in labels:
        res = runs[lab]
        s = res.summary
        t, n = res.evacuation
        row: dict[str, Any] = {
            "label": lab, "model": res.model,
            "t_evac_50": s.get("t_evac_50"), "t_evac_90": s.get("t_evac_90"),
            "t_evac_100": s.get("t_evac_100"), "steps": s.get("steps"),
            "wall_time_s": s.get("wall_time_s"),
        }
        rt, rn = ref.evacuation
        row["evac_curve_distance"] = curve_distance(t1=t, n1=n, t2=rt, n2=rn, n_total=n0)
        row["dT90_s"] = (None if s.get("t_evac_90") is None or ref.summary.get("t_evac_90") is None
                         else s["t_evac_90"] - ref.summary["t_evac_90"])
        fo, fr = _outflow_total(res), ref_flow
        if fo is not None and fr is not None:
            end = min(fo[0][-1], fr[0][-1])
            g = np.arange(0.0, end, 0.5)
            a = np.interp(g, *fo)
            b = np.interp(g, *fr)
            row["outflow_distance"] = float(np.mean(np.abs(a - b)) / max(np.mean(np.abs(b)), 1e-12))
        for tt in density_times:
            r0, r1 = ref_rho[tt], _density_or_none(res, tt, mesh)
            row[f"density_L1_t{tt:g}"] = (None if r0 is None or r1 is None else
                                          density_l1(mesh=mesh, rho1=r1, rho2=r0) / n0)
        rows.append(row)
    _write_tables(out, rows, labels[0])
    _write_stairs(out, runs)
    diagrams = _plots(out, room, mesh, runs, n0, density_times) if plots else {}
    return ComparisonResult(runs, rows, out, diagrams)


#: the files a comparison writes into its folder (beside one run folder per model)
COMPARE_FILES = F.COMPARISON_FILES


def _check_compare_folder(out: Path, labels: list[str]) -> None:
    """A one-line error unless ``out`` is new, empty or a comparison's folder: every entry
    a file a comparison writes or a pedmesh run folder (its summary.json), so that a user's
    files are never written over."""
    if not out.exists():
        return
    if not out.is_dir():
        raise F.RunFolderError(f"{out}: not a folder; choose another --out")
    entries = sorted(out.iterdir(), key=lambda p: p.name)
    runs = [e for e in entries if e.is_dir() and F.good_summary(e) is not None]
    try:
        with open(out / F.COMPARISON_CSV, encoding="utf-8") as f:
            ours = f.readline().startswith("label,model,")
    except (OSError, UnicodeDecodeError):
        ours = False
    for e in entries:
        if e.name.startswith(".") or e in runs or (e.is_dir() and e.name in labels):
            continue  # (a model's folder: its run owns it, and refuses what is not a run)
        if e.name in COMPARE_FILES and (ours or runs):
            continue
        raise F.RunFolderError(f"{out}: not empty and not a pedmesh comparison folder (it holds "
                             f"'{e.name}'); choose another --out (pedmesh does not write into "
                             "other files)")


def _fmt(v, digits=2):
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}f}" if abs(v) >= 0.01 or v == 0 else f"{v:.2e}"
    return str(v)


def _write_tables(out: Path, rows: list[dict], ref: str) -> None:
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with open(out / F.COMPARISON_CSV, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in keys})
    lines = [f"Comparison against `{ref}` (distances: mean |N_out(t) - N_ref(t)|/N, "
             "relative outflow difference, density L1 / N at the given times).", "",
             "| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    for r in rows:
        lines.append("| " + " | ".join(_fmt(r.get(k), 4 if "distance" in k or "L1" in k else 1)
                                       for k in keys) + " |")
    (out / F.COMPARISON_MD).write_text("\n".join(lines) + "\n", encoding="utf-8")


def _write_stairs(out: Path, runs: dict) -> None:
    """A building's stair use per model (summary.json's "stairs",
    :mod:`pedmesh.analysis.stairs`): stairs.csv, and a table added to comparison.md."""
    keys = ("people", "down", "up", "first", "last", "peak_flow", "peak_density")
    rows = [{"label": lab, "stair": name, **{k: u.get(k) for k in keys}}
            for lab, res in runs.items()
            for name, u in (res.summary.get("stairs") or {}).items() if isinstance(u, dict)]
    if not rows:
        return
    with open(out / F.COMPARISON_STAIRS, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=["label", "stair", *keys])
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if v is None else v) for k, v in r.items()})
    lines = ["", "Stair use (people who stepped on, first and last on [s], peak flow over "
             "10 s [ped/s], peak density on the stair [ped/m^2]).", "",
             "| stair | " + " | ".join(runs) + " |", "|" + "---|" * (len(runs) + 1)]
    for name in dict.fromkeys(r["stair"] for r in rows):
        cells = []
        for lab in runs:
            u = next((r for r in rows if r["label"] == lab and r["stair"] == name), None)
            cells.append("-" if u is None else
                         f"{_fmt(u['people'], 1)} people, {_fmt(u['first'], 1)}-"
                         f"{_fmt(u['last'], 1)} s, {_fmt(u['peak_flow'], 2)} /s, "
                         f"{_fmt(u['peak_density'], 2)} /m^2")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    with open(out / F.COMPARISON_MD, "a", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")


def _plots(out, room, mesh, runs, n0, density_times) -> dict:
    """Write the comparison plots; returns the binned density-flow diagrams by label."""
    from .plotting import _plt, plot_density, plot_evacuation, plot_fundamental, plot_outflow

    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 4))
    plot_evacuation(ax, {k: r.evacuation for k, r in runs.items()}, n0)
    fig.tight_layout()
    fig.savefig(out / F.COMPARISON_PLOTS["evacuation"], dpi=120)
    plt.close(fig)
    flows = {k: f for k, r in runs.items() if (f := _outflow_total(r)) is not None}
    if flows:
        fig, ax = plt.subplots(figsize=(6, 4))
        plot_outflow(ax, flows)
        fig.tight_layout()
        fig.savefig(out / F.COMPARISON_PLOTS["outflow"], dpi=120)
        plt.close(fig)
    diagrams = {}
    for k, r in runs.items():
        d, f = _fd_samples(r, mesh)
        if len(d):
            diagrams[k] = density_flow_diagram(density=d, flow=f)
    if diagrams:
        fig, ax = plt.subplots(figsize=(6, 4))
        rr = np.linspace(0, 10.5, 200)
        plot_fundamental(ax, diagrams, (rr, reference_flow(density=rr)))
        fig.tight_layout()
        fig.savefig(out / F.COMPARISON_PLOTS["fundamental"], dpi=120)
        plt.close(fig)
    labels = list(runs)
    nt = len(density_times)
    fig, axes = plt.subplots(nt, len(labels), figsize=(3.2 * len(labels), 1.9 * nt),
                             squeeze=False)
    tp = None
    for i, tt in enumerate(density_times):
        for j, lab in enumerate(labels):
            ax = axes[i, j]
            try:
                ft, rho, _ = runs[lab].density_at(tt, mesh)
                tp = plot_density(ax, mesh, rho, vmax=6.0, room=room)
                ax.set_title(f"{lab}, t = {ft:.0f} s", fontsize=8)
            except Exception:
                ax.set_axis_off()
            ax.set_xlabel("")
            ax.set_ylabel("")
            ax.tick_params(labelsize=6)
    if tp is not None:
        fig.colorbar(tp, ax=axes, shrink=0.8, label="density [ped/m^2]")
    fig.savefig(out / F.COMPARISON_PLOTS["density"], dpi=120)
    plt.close(fig)
    return diagrams
