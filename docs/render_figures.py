"""Render the measured figures of the docs from the benchmarks' own output files.

    python docs/render_figures.py          # writes docs/_generated/figures_*.md

``docs/conf.py`` runs it at every build, so a figure on a page is always the one in the
file a benchmark wrote; no measured figure is typed into a page by hand. The sources:

* ``docs/data/continuum_speed.json``: ``python benchmarks/continuum_speed.py --json FILE``
  (every continuum model against the social force model, whole process);
* ``docs/images/work_precision.csv``: ``python benchmarks/continuum_speed.py --sweep
  --plot docs/images/work_precision.png`` (the CSV is written beside the picture);
* ``docs/data/eikonal.json``: ``python benchmarks/eikonal.py --json FILE``;
* ``docs/data/threads_sfm.json``: ``python benchmarks/threads.py --model sfm --json FILE``
  (the social force model's kernels and whole Example 2 processes on 1, 2, ... threads).
* ``docs/data/sfm_jupedsim.json``: ``python benchmarks/sfm.py --skip-scaling --json FILE``
  (Example 2 under the social force model against JuPedSim's, in the same run).
* ``docs/data/threads_eos.json``: ``python benchmarks/threads.py --model eos --profile 80
  --json FILE`` (eos's kernels and whole steps on the venue on 1, 2, ... threads, and the
  serial share of a one-thread step).
* ``docs/data/convergence.json``: ``python benchmarks/convergence.py --json FILE`` (T50 and
  T90 of every model against the run's mesh, and of the social force model against its
  route mesh's resolution).
* ``docs/data/converged_ab.json``: ``python benchmarks/sfm.py --converged-ab --json FILE``
  (the validated preset's cost per step on Example 2 against the preset before issue 44).
* ``docs/data/startup.json``: ``python benchmarks/startup.py --json FILE`` (the start-up of
  cached ``--t-end 0.1`` runs and whole Example 2 processes, eos against the social force
  model, with ``--against DIR`` also those of another checkout; issue 46).
* ``docs/data/building_steps.json``: ``python benchmarks/building_steps.py --reference
  --json FILE`` (a social force model step of ten people on the top floor of 10- and
  50-floor towers against the same ten in a one-floor room; issue 45).
* ``docs/data/exit_ghosts.json``: ``python benchmarks/exit_ghosts.py --json FILE`` (Example
  2's exit as a line, as a door onto a porch and with people beyond it; issue 44).

To update a figure, re-run its benchmark with the same options into the same file and
commit the file; the JSON records the command, date, machine and load average it was
measured with, and the page says so under each table.
"""

from __future__ import annotations

import csv
import json
import statistics
from pathlib import Path

DOCS = Path(__file__).resolve().parent
DATA = DOCS / "data"
OUT = DOCS / "_generated"


def _table(header: list[str], rows: list[list[str]], align: str = "") -> list[str]:
    """A Markdown table; ``align`` has one character per column, 'l' or 'r' (default r)."""
    align = align.ljust(len(header), "r")
    lines = ["| " + " | ".join(header) + " |",
             "|" + "|".join("---" if a == "l" else "---:" for a in align) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return lines


def _provenance(record: dict, source: str) -> str:
    m = record["machine"]
    load = ", ".join(f"{x:g}" for x in m.get("load_average", []))
    return (f"Rendered from `{source}`: `{record['command']}` on {record['date']}, pedmesh "
            f"{record['pedmesh']}, Python {record['python']}, {m['cpus']} CPUs "
            f"({m['platform']}), load average {load or 'not recorded'} at the end of the "
            "run. The machine may be shared: compare the ratios of one table, not seconds "
            "across tables.")


def continuum_speed(path: Path = DATA / "continuum_speed.json") -> str:
    record = json.loads(path.read_text())
    res = record["results"]
    rows = [[f"`{r['model']}`", f"{r['cells']:,}", f"{r['steps']:,}", f"{r['dt']:.3f}",
             f"{r['wall_median']:.1f}", f"{r['wall_best']:.1f}", f"{r['ratio_median']:.3f}",
             f"{r['ratio_best']:.3f}", f"{r['t50']:.2f}", f"{r['t90']:.2f}",
             "" if r["model"] == "sfm" else f"{r['d50']:+.2f} %",
             "" if r["model"] == "sfm" else f"{r['d90']:+.2f} %",
             "" if r["model"] == "sfm" else f"{r['curve']:.4f}"]
            for r in res["rows"]]
    head = ["model", "cells", "steps", "mean dt [s]", "wall [s] median", "best",
            "wall / SFM median", "best", "T50 [s]", "T90 [s]", "T50 vs SFM", "T90 vs SFM",
            "curve vs SFM"]
    extra = " ".join(res.get("extra") or []) or "no extra options"
    lines = [f"Room `{res['room']}` ({extra}), {res['repeats']} interleaved repeat(s).", ""]
    lines += _table(head, rows, "l")
    lines += ["", _provenance(record, path.relative_to(DOCS.parent).as_posix()), ""]
    return "\n".join(lines)


def work_precision(path: Path = DOCS / "images" / "work_precision.csv") -> str:
    with open(path, newline="") as f:
        data = list(csv.DictReader(f))
    rows = [[f"`{r['model']}`", r["label"], f"{int(r['cells']):,}", f"{int(r['steps']):,}",
             f"{float(r['wall']):.1f}", f"{float(r['d50']):+.2f} %", f"{float(r['d90']):+.2f} %",
             f"{float(r['curve']):.4f}" if r["curve"] else "not recorded"] for r in data]
    head = ["model", "setting", "cells", "steps", "wall [s]", "T50 error", "T90 error",
            "curve error"]
    lines = _table(head, rows, "ll")
    lines += ["", f"Rendered from `{path.relative_to(DOCS.parent).as_posix()}`, the rows "
              "`benchmarks/continuum_speed.py --sweep --plot docs/images/work_precision.png` "
              "wrote beside the picture (the CSV records no date or machine).", ""]
    return "\n".join(lines)


def eikonal(path: Path = DATA / "eikonal.json") -> str:
    record = json.loads(path.read_text())
    res = record["results"]
    rows = [[f"{r['vertices']:,}", f"{1e3 * r['setup_s']:.0f}", f"{1e3 * r['solve_s']:.2f}",
             f"{1e9 * r['solve_s'] / r['vertices']:.0f}", f"{r['l1']:.4f}", f"{r['linf']:.4f}",
             f"{1e3 * r['plain_solve_s']:.2f}", f"{r['plain_l1']:.4f}", f"{r['plain_linf']:.4f}",
             f"{1e3 * r['variable_cost_solve_s']:.2f}"] for r in res["rows"]]
    head = ["vertices", "set-up [ms]", "solve [ms]", "ns/vertex", "L1 [m]", "Linf [m]",
            "plain FMM solve [ms]", "plain L1 [m]", "plain Linf [m]", "variable-cost solve [ms]"]
    lines = [f"pedmesh's fast marching on `{res['room']}`, unit cost, against the exact "
             "geodesic distance; *plain* is Kimmel-Sethian without the corner rays "
             f"(`corner_radius=0`); median of {res['repeats']} repeats.", ""]
    lines += _table(head, rows)
    rows = [[f"{r['vertices']:,}", f"{r['skfmm1']['nodes']:,}", f"{1e3 * r['skfmm1']['t']:.2f}",
             f"{r['skfmm1']['l1']:.4f}", f"{1e3 * r['skfmm2']['t']:.2f}",
             f"{r['skfmm2']['l1']:.4f}",
             f"{(r['solve_s'] / r['vertices']) / (r['skfmm1']['t'] / r['skfmm1']['nodes']):.2f}"]
            for r in res["rows"]]
    head = ["pedmesh vertices", "grid nodes", "order 1 [ms]", "order 1 L1 [m]", "order 2 [ms]",
            "order 2 L1 [m]", "pedmesh / order 1, per node"]
    lines += ["", "scikit-fmm on Cartesian grids of about the same node count, in the same "
              "run:", ""]
    lines += _table(head, rows)
    lines += ["", f"Observed order of the L1 error: {res['order_l1']:.2f} with the corner rays, "
              f"{res['order_l1_plain']:.2f} without.", "",
              _provenance(record, path.relative_to(DOCS.parent).as_posix()), ""]
    return "\n".join(lines)


def _kernel_table(res: dict) -> list[str]:
    """The table of ``benchmarks/threads.py``'s kernels: median / best time on each thread
    count and the ratios to one thread."""
    counts = [str(t) for t in res["threads"]]
    head = ["kernel", *(f"{t} thr. median / best [ms]" for t in counts),
            *(f"x {t} thr. median / best" for t in counts[1:])]
    rows = [[r["kernel"], *(f"{1e3 * r['median_s'][t]:.2f} / {1e3 * r['best_s'][t]:.2f}"
                            for t in counts),
             *(f"{r['ratio_median'][t]:.2f} / {r['ratio_best'][t]:.2f}" for t in counts[1:])]
            for r in res["kernels"]]
    return _table(head, rows, "l")


def threads_sfm(path: Path = DATA / "threads_sfm.json") -> str:
    record = json.loads(path.read_text())
    res = record["results"]
    st = res["state"]
    lines = [f"The social force model ({st['preset']} preset) on `{st['room']}` with "
             f"{st['people']:,} people inside at t = {st['t']:.0f} s ({st['pairs']:,} pairs "
             f"listed), numba's `{res['threading_layer']}` threading layer; each kernel "
             f"{res['repeats']} times per thread count, the counts interleaved; *x N thr.*: "
             "the time on N threads over that on one.", ""]
    lines += _kernel_table(res)
    whole = res.get("example2_processes")
    if whole:
        rows = [[str(r["threads"]), f"{r['median_s']:.1f}", f"{r['best_s']:.1f}",
                 f"{sorted(r['cpu_s'])[len(r['cpu_s']) // 2]:.1f}", f"{r['ratio_median']:.2f}",
                 f"{r['ratio_best']:.2f}"] for r in whole]
        lines += ["", f"Whole `pedmesh run geometries/example2.json --model sfm --preset paper "
                  f"--param threads=N` processes (start-up, output and safety measures "
                  f"included), {len(whole[0]['wall_s'])} per thread count, interleaved; *CPU*: "
                  "user and system time of the process (at most wall time x threads):", ""]
        lines += _table(["threads", "wall median [s]", "wall best [s]", "CPU median [s]",
                         "x median", "x best"], rows)
    lines += ["", _provenance(record, path.relative_to(DOCS.parent).as_posix()), ""]
    return "\n".join(lines)


def threads_eos(path: Path = DATA / "threads_eos.json") -> str:
    record = json.loads(path.read_text())
    res = record["results"]
    st = res["state"]
    lines = [f"`{st['model']}` on `{st['room']}` ({st['cells']:,} cells, {st['inside']:,.0f} "
             f"people inside at t = {st['t']:.0f} s), numba's `{res['threading_layer']}` "
             f"threading layer; each kernel {res['repeats']} times per thread count, the "
             "counts interleaved; *x N thr.*: the time on N threads over that on one.", ""]
    lines += _kernel_table(res)
    prof = res.get("profile")
    if prof:
        lines += ["", f"A profile of {prof['steps']} whole steps on one thread (cProfile, "
                  f"{1e3 * prof['wall_s'] / prof['steps']:.1f} ms a step): the functions' own "
                  "time, *parallel* where it is a kernel whose loops the threads share, "
                  f"*serial* elsewhere. The serial share is **{100 * prof['serial_share']:.1f} "
                  "%** of the profiled time, which bounds the speed-up of N threads to "
                  f"1 / ({prof['serial_share']:.3f} + {1 - prof['serial_share']:.3f} / N) "
                  "(Amdahl).", ""]
        top = [[f"`{f['function'].split(':')[-1]}`", "parallel" if f["parallel"] else "serial",
                f"{100 * f['seconds'] / prof['profiled_s']:.1f}"] for f in prof["functions"][:16]]
        lines += _table(["function", "kind", "share [%]"], top, "l")
    lines += ["", _provenance(record, path.relative_to(DOCS.parent).as_posix()), ""]
    return "\n".join(lines)


def sfm_reference(path: Path = DATA / "sfm_jupedsim.json") -> str:
    record = json.loads(path.read_text())
    res = record["results"]
    e2, j = res["example2"], res["jupedsim"]
    step = res["step_split_s"]["step (all included)"]
    lines = [f"Example 2 (2,400 people, {res['mesh']['triangles']:,} triangles), the paper's "
             "parameters:", ""]
    rows = [["pedmesh, social force model (SSP-RK3, kernel density, routes every 1 s)",
             f"{e2['wall']:.1f}", f"{e2['steps']:,}", f"{1e3 * step:.3f}"]]
    if j:
        rows.append([f"JuPedSim {j['version']} SocialForceModel (forward Euler, dt 0.01 s, no "
                     "rerouting)", f"{j['wall']:.1f}", f"{j['steps']:,}",
                     f"{1e3 * j['per_step']:.3f}"])
    lines += _table(["", "wall [s]", "steps", "one step with 2,400 inside [ms]"], rows, "l")
    if j:
        lines += ["", f"pedmesh / JuPedSim: **{j['ratio_wall']:.3f}** of the wall time, "
                  f"**{j['ratio_step']:.3f}** of a step with everyone inside, in the same run."]
    lines += ["", _provenance(record, path.relative_to(DOCS.parent).as_posix()), ""]
    return "\n".join(lines)


def _t(v, spread=None) -> str:
    if v is None:
        return "-"
    return f"{v:.1f}" + (f" ±{0.5 * spread:.1f}" if spread else "")


def convergence(path: Path = DATA / "convergence.json") -> str:
    """The mesh convergence study of ``benchmarks/convergence.py`` (issue 44)."""
    record = json.loads(path.read_text())
    res = record["results"]
    summary = res["summary"]
    lines = []
    for room, s in summary.items():
        areas = []
        for row in s["rows"]:
            for c in row["meshes"]:
                if c["area"] not in areas:
                    areas.append(c["area"])
        head = ["model", *(f"{a} m²" if a != "default" else "default (graded)" for a in areas)]
        rows = []
        for row in s["rows"]:
            by = {c["area"]: c for c in row["meshes"]}
            cells = []
            for a in areas:
                c = by.get(a)
                if c is None or c["T90"] is None:
                    cells.append("-")
                    continue
                d = "" if a == "default" or c.get("dT90") is None else (
                    f" ({100 * c['dT50']:+.1f} / {100 * c['dT90']:+.1f} %)")
                cells.append(f"{_t(c['T50'], c['T50_spread'])} / "
                             f"{_t(c['T90'], c['T90_spread'])}{d}")
            rows.append([f"`{row['model']}`", *cells])
        if rows:
            lines += [f"**{room}**: T50 / T90 [s] on each mesh (the social force model: mean "
                      f"of seeds {', '.join(map(str, res.get('seeds', [0, 1])))}, ± half "
                      "their spread; in brackets the change against the default mesh)", ""]
            lines += _table(head, rows, "l" * len(head))
        if s["resolution"]:
            lines += ["", f"**{room}**, `sfm-validated` at the default mesh against its route "
                      "mesh's `route_resolution`:", ""]
            lines += _table(["route_resolution [m]", "T50 [s]", "T90 [s]"],
                            [[f"{r['resolution']:g}", _t(r["T50"], r["T50_spread"]),
                              _t(r["T90"], r["T90_spread"])] for r in s["resolution"]])
        if s.get("refine") and room == "door":
            lines += ["", "**door** (the 60-person, 0.8 m door of tests/sfm/test_routes.py), "
                      "`sfm-validated` with every edge of its route mesh divided by "
                      f"`route_refine` (1: the preset); mean of {s['refine'][0]['n']} seeds ± "
                      "the standard error, in brackets the change against the preset:", ""]
            base = s["refine"][0]
            lines += _table(["route_refine", "route mesh triangles", "T50 [s]", "T90 [s]"],
                            [[f"{r['refine']:g}", f"{r['route_mesh']:,}"
                              if r.get("route_mesh") else "-",
                              *(f"{r[k]:.2f} ± {r[k + '_se']:.2f}"
                                + ("" if r is base else
                                   f" ({100 * (r[k] / base[k] - 1):+.1f} %)")
                                for k in ("T50", "T90"))]
                             for r in s["refine"]])
        elif s.get("refine"):
            lines += ["", f"**{room}**, `sfm-validated` at the default mesh with every edge of "
                      "its route mesh divided by `route_refine` (1: the preset):", ""]
            lines += _table(["route_refine", "route mesh triangles", "T50 [s]", "T90 [s]"],
                            [[f"{r['refine']:g}", f"{r['route_mesh']:,}"
                              if r.get("route_mesh") else "-",
                              _t(r["T50"], r["T50_spread"]), _t(r["T90"], r["T90_spread"])]
                             for r in s["refine"]])
        if s.get("kernel"):
            lines += ["", f"**{room}**, `sfm-validated` at the default mesh against its "
                      "`route_kernel` (the model, not the numerics):", ""]
            lines += _table(["route_kernel [m]", "T50 [s]", "T90 [s]"],
                            [[f"{r['kernel']:g}", _t(r["T50"], r["T50_spread"]),
                              _t(r["T90"], r["T90_spread"])] for r in s["kernel"]])
        lines.append("")
    lines += [_provenance(record, path.relative_to(DOCS.parent).as_posix()), ""]
    return "\n".join(lines)


def converged_ab(path: Path = DATA / "converged_ab.json") -> str:
    """The cost per step of issue 44's validated preset against the one before it
    (``benchmarks/sfm.py --converged-ab``)."""
    record = json.loads(path.read_text())
    res = record["results"]
    rows = []
    for key, r in res["converged_ab"].items():
        rows.append([f"`{key}`", f"{r['triangles']:,}",
                     *(f"{1e3 * statistics.median(r[k]):.3f}" for k in
                       ("step", "forces", "settle", "routing")),
                     f"{1e3 * min(r['step']):.3f}"])
    lines = _table(["preset", "triangles walked on", "step [ms] (median)", "forces", "settle",
                    "routing", "step (best)"], rows)
    lines += ["", f"Ratio validated / before: median {res['ratio_median']:.2f}, best "
              f"{res['ratio_best']:.2f} (the issue's goal: at most 1.20).", "",
              _provenance(record, path.relative_to(DOCS.parent).as_posix()), ""]
    return "\n".join(lines)


def startup(path: Path = DATA / "startup.json") -> str:
    """The start-up and whole-process times of ``benchmarks/startup.py`` (issue 46)."""
    record = json.loads(path.read_text())
    res = record["results"]
    names = {"this": "this checkout",
             "against": f"against: {res.get('against_label') or res.get('against')}"}
    lines = []
    parts = [("startup", "Start-up, numba's cache warm"), ("whole", "Whole Example 2 process")]
    for key, title in parts:
        part = res.get(key)
        if not part:
            continue
        rows = []
        for k, c in part["checkouts"].items():
            m = c["models"]
            rows.append([names.get(k, k), f"{m['eos']['median_s']:.2f}",
                         f"{m['eos']['best_s']:.2f}", f"{m['sfm']['median_s']:.2f}",
                         f"{m['sfm']['best_s']:.2f}", f"{c['ratio_median']:.3f}",
                         f"{c['ratio_best']:.3f}"])
        lines += [f"**{title}**: `{part['command']}`, {part['repeats']} interleaved "
                  "repeat(s) of each.", ""]
        lines += _table(["", "eos median [s]", "best", "sfm median [s]", "best",
                         "eos / sfm median", "best"], rows, "l")
        lines.append("")
        if part.get("floor"):
            f = part["floor"]
            eos = part["checkouts"]["this"]["models"]["eos"]
            lines += [f"*Floor* (the libraries every run imports and one cached numba kernel, "
                      f"interleaved with the runs): median {f['median_s']:.2f} s, best "
                      f"{f['best_s']:.2f} s; the eos start-up beyond it, pedmesh's own: "
                      f"median {eos['median_s'] - f['median_s']:.2f} s, best "
                      f"{eos['best_s'] - f['best_s']:.2f} s.", ""]
        for model, differ in part.get("files_differing", {}).items():
            lines += [f"`{model}`: output files of both checkouts the same bytes (summary.json "
                      "apart): " + ("yes." if not differ else f"**no** ({', '.join(differ)})."),
                      ""]
    this = res["startup"]["checkouts"]["this"]["models"]["eos"]
    lines.append(f"Targets (issue 46): the cached eos start-up at most {res['target_start_s']} s "
                 f"(median {this['median_s']:.2f} s: "
                 f"**{'met' if res.get('startup_met') else 'not met'}**)")
    if "whole" in res:
        w = res["whole"]["checkouts"]["this"]
        lines[-1] += (f"; the whole eos process at most {res['target_ratio']} of the social "
                      f"force model's (median {w['ratio_median']:.3f}: "
                      f"**{'met' if res.get('whole_met') else 'not met'}**)")
    lines[-1] += "."
    if res.get("pythondontwritebytecode"):
        lines += ["", "Measured with `PYTHONDONTWRITEBYTECODE` set: no byte code cached, every "
                  "module compiled from source at every start."]
    lines += ["", _provenance(record, path.relative_to(DOCS.parent).as_posix()), ""]
    return "\n".join(lines)


def building_steps(path: Path = DATA / "building_steps.json") -> str:
    """A step on a tall building against one in a room (``benchmarks/building_steps.py``,
    issue 45)."""
    record = json.loads(path.read_text())
    res = record["results"]
    rows = []
    for r in sorted(res["rows"], key=lambda r: (r["levels"], r["whole_solves"])):
        what = ("the one-floor room" if r["levels"] == 1 else
                f"{r['levels']}-floor tower" + (", whole route solves" if r["whole_solves"]
                                                else ""))
        marched = "" if r["marched"] is None else f"{r['marched']:,}"
        rows.append([what, f"{r['vertices']:,}", marched, f"{r['median_ms']:.3f}",
                     f"{r['best_ms']:.3f}", f"{r['routing_median_ms']:.3f}",
                     f"{r['ratio_median']:.2f}", f"{r['ratio_best']:.2f}"])
    lines = [f"{res['people']} people, steps {res['warmup'] + 1}-{res['warmup'] + res['steps']} "
             f"of each run, {res['repeats']} interleaved repeats; *marched*: the vertices the "
             "last route solve marched (of the surface's *vertices*).", ""]
    lines += _table(["", "vertices", "marched", "ms/step median", "best", "routing [ms/step]",
                     "x room median", "best"], rows, "l")
    top = max(res["levels"])
    lines += ["", f"Goal (issue 45): a step of the {top}-floor tower at most {res['target']:g} "
              f"times the room's: **{'met' if res['met'] else 'not met'}**.", "",
              _provenance(record, path.relative_to(DOCS.parent).as_posix()), ""]
    return "\n".join(lines)


def exit_ghosts(path: Path = DATA / "exit_ghosts.json") -> str:
    """Example 2's exit as a line, as a door onto a porch and with people beyond it
    (``benchmarks/exit_ghosts.py``, issue 44)."""
    record = json.loads(path.read_text())
    res = record["results"]
    what = {"line": "the exit line, people removed on it",
            "porch": "a door in a 0.2 m wall onto a 10 x 30 m porch",
            "ghosts": "the exit line, people beyond it in the density (`exit_ghosts=1`)"}

    def stat(case, key):
        v = [r[key] for r in res["rows"] if r["case"] == case]
        return statistics.fmean(v), min(v), max(v)

    rows = []
    for case in ("line", "porch", "ghosts"):
        f, t50, t90 = (stat(case, k) for k in ("flow_per_m_s", "T50_s", "T90_s"))
        rows.append([f"SFM, {what[case]}", f"{f[0]:.2f} ({f[1]:.2f}-{f[2]:.2f})",
                     f"{t50[0]:.1f} ({t50[1]:.1f}-{t50[2]:.1f})",
                     f"{t90[0]:.1f} ({t90[1]:.1f}-{t90[2]:.1f})"])
    e = next(r for r in res["rows"] if r["case"] == "eos")
    rows.append(["eos, the exit line", f"{e['flow_per_m_s']:.2f}", f"{e['T50_s']:.1f}",
                 f"{e['T90_s']:.1f}"])
    g50, g90 = stat("ghosts", "T50_s")[0], stat("ghosts", "T90_s")[0]
    l50, l90 = stat("line", "T50_s")[0], stat("line", "T90_s")[0]
    lines = [f"Example 2 (2,400 people, a 10 m exit) under `validated`; the social force model "
             f"the mean of seeds {', '.join(map(str, res['seeds']))} (their range in "
             "brackets). Flow: through x = 100 m between the 10th and the 90th percentile of "
             "the crossings; T50/T90: when half and nine tenths had crossed x = 100 m.", ""]
    lines += _table(["", "flow [1/(m s)]", "T50 [s]", "T90 [s]"], rows, "l")
    lines += ["", f"eos against the social force model (T50 / T90): "
              f"{100 * (e['T50_s'] / g50 - 1):+.1f} / {100 * (e['T90_s'] / g90 - 1):+.1f} % "
              f"with people beyond the exit, {100 * (e['T50_s'] / l50 - 1):+.1f} / "
              f"{100 * (e['T90_s'] / l90 - 1):+.1f} % against the exit line alone.", "",
              _provenance(record, path.relative_to(DOCS.parent).as_posix()), ""]
    return "\n".join(lines)


def meshing(path: Path = DATA / "meshing.json") -> str:
    """The route mesh's build time with compiled distances against GEOS's nearest search
    (``benchmarks/meshing.py``)."""
    record = json.loads(path.read_text())
    res = record["results"]
    rows = []
    for name, r in res["sites"].items():
        rows.append([f"`{name}`", f"{r['triangles']:,}", f"{r['compiled_median_s']:.2f}",
                     f"{r['compiled_best_s']:.2f}", f"{r['geos_median_s']:.2f}",
                     f"{r['geos_best_s']:.2f}", f"{r['speed_up']:.1f}",
                     "yes" if r["same_mesh"] else "**no**"])
    lines = [f"The route mesh of `validated` (route_resolution {res['resolution_m']:g} m, "
             f"route_kernel {res['kernel_m']:g} m, route_clearance {res['clearance_m']:g} m), "
             f"built {res['repeats']} times each way, interleaved; *same mesh*: every build "
             "gave the same points and triangles, bit for bit.", ""]
    lines += _table(["geometry", "triangles", "compiled median [s]", "best", "GEOS median [s]",
                     "best", "GEOS / compiled", "same mesh"], rows, "l")
    lines += ["", _provenance(record, path.relative_to(DOCS.parent).as_posix()), ""]
    return "\n".join(lines)


def compile_time(path: Path = DATA / "compile_time.json") -> str:
    """A fresh install's compilation of a room under four models and a two-storey building
    (``benchmarks/compile_time.py``)."""
    record = json.loads(path.read_text())
    res = record["results"]
    rows = []
    for label, r in res["checkouts"].items():
        rows.append([label, f"{r['compile_median_s']:.0f}", f"{r['compile_best_s']:.0f}",
                     f"{r['wall_median_s']:.0f}", f"{r['compilations']}",
                     ", ".join(f"`{k.rsplit('.', 1)[-1]}`" for k in r["compiled_twice"])
                     or "none"])
    lines = [f"Workload: {res['workload']}; each checkout in a new process with an empty "
             f"numba cache, {next(iter(res['checkouts'].values()))['repeats']} time(s), "
             "interleaved.", ""]
    lines += _table(["checkout", "compiling, median [s]", "best", "process, median [s]",
                     "compilations", "kernels compiled twice"], rows, "lrrrrl")
    if "ratio_median" in res:
        lines += ["", f"Compile time, this checkout against the other: median "
                      f"{res['ratio_median']:.2f}, best {res['ratio_best']:.2f}."]
    first = next(iter(res["checkouts"].values()))
    lines += ["", "The kernels that took longest (this checkout; the kernels they compile on "
                  "the way counted as theirs):", ""]
    lines += _table(["kernel", "compiling [s]"],
                    [[f"`{k.removeprefix('pedmesh.')}`", f"{v:.1f}"]
                     for k, v in list(first["kernels_s"].items())[:10]], "l")
    lines += ["", _provenance(record, path.relative_to(DOCS.parent).as_posix()), ""]
    return "\n".join(lines)


SECTIONS = {"figures_continuum_speed.md": continuum_speed,
            "figures_work_precision.md": work_precision,
            "figures_eikonal.md": eikonal,
            "figures_threads_sfm.md": threads_sfm,
            "figures_threads_eos.md": threads_eos,
            "figures_sfm_jupedsim.md": sfm_reference,
            "figures_convergence.md": convergence,
            "figures_converged_ab.md": converged_ab,
            "figures_startup.md": startup,
            "figures_building_steps.md": building_steps,
            "figures_exit_ghosts.md": exit_ghosts,
            "figures_meshing.md": meshing,
            "figures_compile_time.md": compile_time}


def main(out_dir: Path = OUT) -> list[Path]:
    """Write every section into ``out_dir`` (a file only if it changed); returns the paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for name, render in SECTIONS.items():
        path = out_dir / name
        text = render()
        if not path.exists() or path.read_text(encoding="utf-8") != text:
            path.write_text(text, encoding="utf-8")
        written.append(path)
    return written


if __name__ == "__main__":
    for p in main():
        print(f"wrote {p}")
