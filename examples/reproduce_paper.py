"""Reproduce every numerical figure of Yang, Yu & Du for Examples 1-3 and check its claims.

    python examples/reproduce_paper.py [--out examples/results] [--quick] [--small]
                                       [--examples example3]

For each example the models run through ``pedmesh.compare`` (finished runs are reused, so
an interrupted reproduction resumes), then the paper's figures are drawn:

* ``fig_f4_evacuation.png``: pedestrians out against time, Examples 1-3 (f4);
* ``fig_f5_sfm_snapshots.png``: the social force crowd of Example 2 at t = 0, 30, 50, 70,
  90, 120 s (f5);
* ``fig_f6_density_example2.png``, ``fig_f7_density_example3.png``: SFM (kernel density)
  and mac1 side by side at the paper's times (f6, f7);
* ``fig_f8_outflow.png``: exit outflow f_c(t), Examples 2 and 3 (f8);
* ``fig_f9_fundamental.png``: the local density-flow diagram, Examples 1-3 (f9);

and ``RESULTS.md`` tabulates T50/T90/T100 per model and example, the distance of every
continuum model from the SFM, and states for each of the paper's claims whether these runs
confirm it. The VTK series of every run stay in ``<out>/example*/<model>/``.
``--quick`` runs a reduced set (for a smoke test), not the paper's figures. ``--small``
runs every example in its room scaled down five times in length (20 x 10 m, about 100
people instead of 2400; the rooms are written to ``<out>/rooms/``, and ``--out`` defaults
to ``examples/results-small``): a check that the whole script runs, in seconds with
``--quick`` (``tests/test_examples.py``), not the paper's results. ``--examples``
and ``--only`` (run labels such as ``mac1,pw_c01``) restrict the runs, with
``--no-figures``, to spread them over several processes that must not share a run
(finished runs are reused through the results folder; a final plain invocation draws every
figure and writes RESULTS.md).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from pedmesh.mesh import triangulate

ROOT = Path(__file__).resolve().parents[1]

MODELS = {
    "example1": "sfm,mac1,rdue,pw:c0=1,mac2-local,eos",
    # eos with the transmissive exit is left out: on Example 2 its outflow stalls (a jam of
    # about 9.7 ped/m^2 at the door, 592 of 2400 out at t = 202 s); see DISCUSSION.md
    "example2": "sfm,mac1,rdue,pw:c0=0.5,pw:c0=1,pw:c0=2,mac2-local,eos,eos:exit=vacuum",
    "example3": "sfm,mac1,rdue,mac2-local,eos",
}
DENSITY_TIMES = {"example1": [30, 50, 70], "example2": [30, 50, 70, 90],
                 "example3": [30, 50, 80, 100]}
QUICK = {"example1": "sfm,rdue", "example2": "sfm,rdue", "example3": "sfm,rdue"}
#: ``--small``: the examples' rooms scaled by this factor in length
SMALL_SCALE = 0.2


def scaled_room(example: str, scale: float, folder: Path) -> Path:
    """``geometries/<example>.json`` with every coordinate times ``scale``, written to
    ``folder``; the start areas keep their spacing, so the crowd shrinks by ``scale**2``."""
    room = json.loads((ROOT / "geometries" / f"{example}.json").read_text())

    def points(pts):
        return [[scale * x, scale * y] for x, y in pts]

    room["outline"] = points(room["outline"])
    for key in ("exits", "obstacles", "start_areas", "measurement_lines", "measurement_areas"):
        for item in room.get(key, []):
            for shape in ("polyline", "polygon"):
                if shape in item:
                    item[shape] = points(item[shape])
    room["name"] = f"{example}-small"
    room["description"] = f"{example} scaled by {scale:g} in length (reproduce_paper.py --small)"
    path = folder / f"{example}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(room, indent=1) + "\n")
    return path


def setup(out: str | Path = ROOT / "examples" / "results", quick: bool = False,
          examples=("example1", "example2", "example3"), max_area: float = 0.5,
          only: set[str] | None = None, scale: float = 1.0) -> dict:
    """Run (or reuse) every model of every example (or only the run labels in ``only``),
    in rooms scaled by ``scale`` in length (:func:`scaled_room`) unless it is 1; returns
    {example: ComparisonResult}."""
    from pedmesh import load_room
    from pedmesh.compare import parse_model_specs, run_comparison
    from pedmesh.models import model_names

    REGISTERED = model_names()

    out = Path(out)
    results = {}
    for ex in examples:
        models = (QUICK if quick else MODELS)[ex]
        specs = [s for s in parse_model_specs(
            ",".join(m for m in models.split(",") if m.split(":")[0] in REGISTERED))
            if only is None or s.label in only]
        if not specs:
            continue
        geometry = f"geometries/{ex}.json"
        if scale != 1.0:
            geometry = str(scaled_room(ex, scale, out / "rooms").resolve())
        room = load_room(ROOT / geometry)  # (an absolute path stays itself)
        mesh = triangulate(room, max_area=max_area, feature_area=None)  # (uniform, as the results)
        t0 = time.perf_counter()
        print(f"== {ex}: {', '.join(s.label for s in specs)}", file=sys.stderr)
        results[ex] = (room, mesh, run_comparison(
            room, mesh, specs, out / ex, geometry=geometry,
            mesh_options={"max_area": max_area, "min_angle": 30.0, "feature_area": None,
                          "exit_size": None},
            density_times=DENSITY_TIMES[ex], quiet=False))
        print(f"== {ex} done in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    return results


# ------------------------------------------------------------------ figures
def figures(results: dict, out: Path) -> None:
    from pedmesh.analysis import reference_flow
    from pedmesh.compare import _outflow_total
    from pedmesh.plotting import _plt, plot_crowd, plot_density, plot_fundamental

    plt = _plt()
    exs = list(results)
    # f4: evacuation curves
    fig, axes = plt.subplots(1, len(exs), figsize=(5 * len(exs), 3.6), squeeze=False)
    for ax, ex in zip(axes[0], exs):
        _, _, cmp = results[ex]
        for lab, r in cmp.runs.items():
            ax.plot(*r.evacuation, label=lab, lw=1.6 if lab in ("sfm", "mac1") else 1.0)
        ax.set_title(ex.replace("example", "Example "))
        ax.set_xlabel("t [s]")
        ax.set_ylabel("pedestrians out")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "fig_f4_evacuation.png", dpi=110)
    plt.close(fig)
    # f5: SFM snapshots of Example 2
    if "example2" in results and "sfm" in results["example2"][2].runs:
        import pyvista as pv

        room, _, cmp = results["example2"]
        reader = pv.PVDReader(cmp.runs["sfm"].path / "pedestrians.pvd")
        tv = np.asarray(reader.time_values)
        fig, axes = plt.subplots(2, 3, figsize=(12, 4.6))
        for ax, t in zip(axes.ravel(), (0, 30, 50, 70, 90, 120)):
            k = int(np.argmin(np.abs(tv - t)))
            reader.set_active_time_value(tv[k])
            pts = np.asarray(reader.read()[0].points)[:, :2]
            plot_crowd(ax, room, pts, size=1.0)
            ax.set_title(f"t = {tv[k]:.0f} s ({len(pts)} inside)", fontsize=9)
        fig.tight_layout()
        fig.savefig(out / "fig_f5_sfm_snapshots.png", dpi=110)
        plt.close(fig)
    # f6, f7: SFM and mac1 densities side by side
    for ex, name in (("example2", "f6"), ("example3", "f7")):
        if ex not in results:
            continue
        room, mesh, cmp = results[ex]
        pair = [m for m in ("sfm", "mac1") if m in cmp.runs]
        times = DENSITY_TIMES[ex]
        fig, axes = plt.subplots(len(times), len(pair), figsize=(5.2 * len(pair), 2.5 * len(times)),
                                 squeeze=False, layout="constrained")
        tp = None
        for i, t in enumerate(times):
            for j, lab in enumerate(pair):
                ax = axes[i, j]
                try:
                    ft, rho, _ = cmp.runs[lab].density_at(t, mesh)
                except Exception:
                    ax.set_axis_off()
                    continue
                tp = plot_density(ax, mesh, rho, vmax=6.0, room=room)
                ax.set_title(f"{lab}, t = {ft:.0f} s", fontsize=9)
        if tp is not None:
            fig.colorbar(tp, ax=axes, shrink=0.7, label="density [ped/m^2]")
        fig.savefig(out / f"fig_{name}_density_{ex}.png", dpi=110)
        plt.close(fig)
    # f8: outflow
    exo = [e for e in ("example2", "example3") if e in results]
    if exo:
        fig, axes = plt.subplots(1, len(exo), figsize=(6 * len(exo), 3.6), squeeze=False)
        for ax, ex in zip(axes[0], exo):
            _, _, cmp = results[ex]
            for lab, r in cmp.runs.items():
                f = _outflow_total(r)
                if f is not None:
                    ax.plot(*f, label=lab + (" (crossing rate)" if lab == "sfm" else ""),
                            lw=1.4 if lab in ("sfm", "mac1") else 0.8)
                if lab == "sfm":
                    fk = _outflow_total(r, kernel=True)
                    if fk is not None:
                        ax.plot(*fk, "k:", lw=0.8, label="sfm (kernel f_c)")
            ax.set_title(ex.replace("example", "Example "))
            ax.set_xlabel("t [s]")
            ax.set_ylabel("outflow f_c [ped/s]")
            ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(out / "fig_f8_outflow.png", dpi=110)
        plt.close(fig)
    # f9: fundamental diagrams
    fig, axes = plt.subplots(1, len(exs), figsize=(5 * len(exs), 3.6), squeeze=False)
    rr = np.linspace(0, 10.5, 200)
    for ax, ex in zip(axes[0], exs):
        plot_fundamental(ax, results[ex][2].diagrams, (rr, reference_flow(density=rr)))
        ax.set_title(ex.replace("example", "Example "))
    fig.tight_layout()
    fig.savefig(out / "fig_f9_fundamental.png", dpi=110)
    plt.close(fig)


# ------------------------------------------------------------------ RESULTS.md
def _first_out(r, fraction=0.01):
    """Time [s] at which ``fraction`` of the crowd is out (interpolated in the curve)."""
    from pedmesh.run import evacuation_times_from_curve

    t, n = r.evacuation
    return evacuation_times_from_curve(t, n, float(r.summary["n_initial"]), (fraction,))[0]


def extent_section(results: dict, times=(20.0, 40.0, 60.0)) -> list[str]:
    """Where the crowd is: the rear and front of the mass along x (every example walks in
    +x; 1st and 99th percentiles of the cell masses) and the peak cell density, per model.
    Shows how far each continuum crowd spreads compared with the SFM's."""
    lines = ["", "## How the crowds spread", "",
             "Rear / front of the crowd along x [m] (1st / 99th percentile of the mass) and "
             "the peak cell density [ped/m^2] at the times shown; the block starts at "
             "0-48 m. SFM densities are the kernel densities (R = 0.7 m) on the cells.", ""]
    from pedmesh.errors import PedmeshError

    head = " | ".join(f"t = {t:g} s" for t in times)
    lines += [f"| example | model | {head} |", "|---|---|" + "---|" * len(times)]
    for ex, (_, mesh, cmp) in results.items():
        x = mesh.centroids[:, 0]
        order = np.argsort(x)
        for lab, r in cmp.runs.items():
            cells = []
            for t in times:
                try:
                    ft, rho, _ = r.density_at(t, mesh)
                except PedmeshError:  # a run without density frames
                    cells.append("-")
                    continue
                m = (rho * mesh.areas)[order]
                if m.sum() <= 0:
                    cells.append("empty")
                    continue
                cm = np.cumsum(m) / m.sum()
                rear = x[order][min(np.searchsorted(cm, 0.01), len(x) - 1)]
                front = x[order][min(np.searchsorted(cm, 0.99), len(x) - 1)]
                cells.append(f"{rear:.1f} / {front:.1f} ({rho.max():.2f})")
            lines.append(f"| {ex[-1]} | {lab} | " + " | ".join(cells) + " |")
    return lines


def _f(v, d=1):
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.{d}f}"


def results_md(results: dict, out: Path, wall: dict | None = None) -> str:
    lines = ["# Reproduction of Yang, Yu & Du, Examples 1-3", "",
             "Generated by `examples/reproduce_paper.py` (all runs on a uniform mesh of "
             "max_area 0.5 m^2). Times in seconds. Distances are against the social force "
             "model (sfm) of the same example: mean |N_out(t) - N_sfm(t)|/N for the "
             "evacuation curves, mean |f_c - f_c,sfm| / mean f_c,sfm for the outflow.", ""]
    cfls = sorted({float(c) for (_, _, cmp) in results.values() for r in cmp.runs.values()
                   if (c := r.summary.get("parameters", {}).get("cfl")) is not None})
    if cfls:
        lines += [f"The continuum runs used CFL {', '.join(f'{c:g}' for c in cfls)} "
                  "(`cfl` in each run's summary.json).", ""]
    lines += ["## Evacuation times", "",
              "| example | model | T50 | T90 | T100 | first 1 % out | curve distance "
              "| outflow distance | steps | wall [s] |",
              "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for ex, (_, _, cmp) in results.items():
        for row in cmp.rows:
            r = cmp.runs[row["label"]]
            lines.append(
                f"| {ex[-1]} | {row['label']} | {_f(row['t_evac_50'])} | {_f(row['t_evac_90'])} | "
                f"{_f(row['t_evac_100'])} | {_f(_first_out(r))} | "
                f"{_f(row['evac_curve_distance'], 4)} | {_f(row.get('outflow_distance'), 3)} | "
                f"{row['steps']} | {_f(row['wall_time_s'], 0)} |")
    lines += ["", "## The paper's claims", ""]
    # claim 1: ordering of the examples
    def t_of(ex, model, key):
        for row in results[ex][2].rows:
            if row["label"] == model:
                return row[key]
        return None

    for model in ("sfm", "mac1"):
        if all(ex in results for ex in ("example1", "example2", "example3")):
            t = {ex: t_of(ex, model, "t_evac_100") for ex in results}
            if None in t.values():
                continue
            ok = t["example1"] < t["example3"] < t["example2"]
            lines.append(f"* **Example 1 evacuates fastest, then Example 3, then Example 2** "
                         f"({model}, T100 = {t['example1']:.1f} / {t['example3']:.1f} / "
                         f"{t['example2']:.1f} s): {'confirmed' if ok else 'NOT confirmed'}.")
    for ex in results:
        rows = {r["label"]: r for r in results[ex][2].rows}
        if "mac1" in rows and "sfm" in rows:
            d = rows["mac1"]["evac_curve_distance"]
            dt90 = rows["mac1"]["dT90_s"]
            verdict = ("confirmed (within 5 %)" if d < 0.05
                       else "NOT confirmed (more than 5 % apart)")
            lines.append(f"* **SFM and mac1 give comparable evacuation curves** ({ex}): mean "
                         f"|N_mac1 - N_sfm|/N = {d:.3f}, T90 differs by {_f(dt90)} s: "
                         f"{verdict}.")
            od = rows["mac1"].get("outflow_distance")
            if od is not None:
                lines.append(f"* **their outflow curves nearly overlap** ({ex}): relative "
                             f"distance {od:.3f}: "
                             f"{'confirmed' if od < 0.15 else 'NOT confirmed'} (criterion 15 %).")
    if "example2" in results:
        runs = results["example2"][2].runs
        t_sfm = _first_out(runs["sfm"]) if "sfm" in runs else None
        if t_sfm is not None:
            parts = []
            verdict = True
            for lab, r in runs.items():
                if lab == "sfm":
                    continue
                t1 = _first_out(r)
                earlier = t1 is not None and t1 < t_sfm
                if lab.startswith("rdue"):
                    verdict &= not earlier
                else:
                    verdict &= earlier
                parts.append(f"{lab} {_f(t1)} s")
            lines.append(f"* **continuum models other than RDUE start evacuating earlier than the "
                         f"SFM** (Example 2, time to the first 1 % out; sfm {t_sfm:.1f} s; "
                         f"{', '.join(parts)}): "
                         f"{'confirmed' if verdict else 'NOT confirmed for every model'}.")
    lines += extent_section(results)
    lines += eos_section(results)
    text = "\n".join(lines) + "\n"
    return text


def eos_section(results: dict) -> list[str]:
    """The calibrated model against the SFM (issue criteria: T50 and T90 within 3 %, mean
    |N_out - N_sfm|/N at most 1.5 %, mass conserved), beside the other continuum models,
    the exit conditions of eos, and the equation of state beside the mean field."""
    from pedmesh.calibration import load_eos

    lines = ["", "## The calibrated continuum model (eos) against the SFM", "",
             "Deviation from the SFM of the same example: (T - T_sfm)/T_sfm for T50 and T90, "
             "mean |N_out(t) - N_sfm(t)|/N for the curve; criteria for eos: 3 %, 3 %, 1.5 %.",
             "", "| example | model | exit | dT50 | dT90 | curve distance | max mass error "
             "| meets the eos criteria |",
             "|---|---|---|---:|---:|---:|---:|---|"]
    verdicts = []
    for ex, (_, _, cmp) in results.items():
        rows = {r["label"]: r for r in cmp.rows}
        if "sfm" not in rows:
            continue
        s50, s90 = rows["sfm"]["t_evac_50"], rows["sfm"]["t_evac_90"]
        for lab, r in rows.items():
            if lab == "sfm" or r["t_evac_50"] is None or r["t_evac_90"] is None:
                continue
            d50 = (r["t_evac_50"] - s50) / s50
            d90 = (r["t_evac_90"] - s90) / s90
            cd = r["evac_curve_distance"]
            ok = abs(d50) <= 0.03 and abs(d90) <= 0.03 and cd <= 0.015
            summ = cmp.runs[lab].summary
            me = summ.get("mass_error_max")
            if lab == "eos":
                verdicts.append(ok)
            mass = _f(me, 1) if me is None else f"{me:.1e}"
            lines.append(f"| {ex[-1]} | {lab} | {summ.get('exit_condition', '-')} | "
                         f"{100 * d50:+.1f} % | {100 * d90:+.1f} % | {100 * cd:.2f} % | {mass} | "
                         f"{'yes' if ok else 'no'} |")
    if verdicts:
        lines += ["", "**eos with the shipped calibration and the exact exit meets the criteria "
                  f"on {sum(verdicts)} of {len(verdicts)} examples.**"]
    cal = load_eos()
    lines += ["", "### The measured equation of state (shipped calibration)", "",
              "| rho [ped/m^2] | p measured [ped/s^2] | standard error | gamma1 rho^2/2 | ratio |",
              "|---:|---:|---:|---:|---:|"]
    for r in cal["table"]:
        lines.append(f"| {r['rho']:g} | {r['p']:.3e} | {r['p_err']:.1e} | {r['mean_field']:.3e} | "
                     f"{r['p'] / r['mean_field']:.2e} |")
    opts = cal["options"]
    lines += ["", f"gamma1 = {cal['gamma1']:.4f} m^4/s^2; measured in {opts['n']}-pedestrian "
              f"periodic boxes, {opts['replicas']} replicas, {opts['relax_time']:g} s "
              f"relaxation + {opts['sample_time']:g} s averaging. The flowing-crowd check is "
              "in `eos_flowing_check.md`."]
    return lines


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=None,
                    help="results folder (default: examples/results, with --small "
                         "examples/results-small)")
    ap.add_argument("--quick", action="store_true", help="a reduced smoke run, not the paper set")
    ap.add_argument("--small", action="store_true",
                    help=f"rooms scaled by {SMALL_SCALE:g} in length (a smoke run)")
    ap.add_argument("--examples", default="example1,example2,example3",
                    help="comma-separated subset of example1,example2,example3")
    ap.add_argument("--only", default=None, help="comma-separated run labels (e.g. mac1,pw_c01)")
    ap.add_argument("--no-figures", action="store_true", help="only run the models")
    a = ap.parse_args(argv)
    examples = tuple(e.strip() for e in a.examples.split(",") if e.strip())
    unknown = [e for e in examples if e not in MODELS]
    if unknown or not examples:
        ap.error(f"unknown example(s) {unknown}; choose from {', '.join(MODELS)}")
    out = Path(a.out or ROOT / "examples" / ("results-small" if a.small else "results"))
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    only = None if a.only is None else {x.strip() for x in a.only.split(",") if x.strip()}
    results = setup(out, quick=a.quick, examples=examples, only=only,
                    scale=SMALL_SCALE if a.small else 1.0)
    if a.no_figures:
        print(f"runs done in {time.perf_counter() - t0:.0f} s (no figures)", file=sys.stderr)
        return
    figures(results, out)
    text = results_md(results, out)
    notes = out / "DISCUSSION.md"
    if notes.exists():
        text += "\n" + notes.read_text()
    (out / "RESULTS.md").write_text(text, encoding="utf-8")
    print(f"done in {time.perf_counter() - t0:.0f} s; see {out / 'RESULTS.md'}", file=sys.stderr)


if __name__ == "__main__":
    main()
