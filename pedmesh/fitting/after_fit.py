"""Everything that follows a refit of the ``validated`` preset, in order, resumable.

A refit changes the shipped model, so every figure measured with it is stale: the
continuum models' table and equation of state (measured from the social force model), the
mesh convergence study, the door probes, the validation tables, the RiMEA tests, eos
against the social force model, and the docs rendered from them. This runs those steps one
after another, each in a process of its own with its output in a log file, and marks each
step done (a file in the log directory) as it ends, so that an interrupted chain
continues where it stopped::

    python -m pedmesh.fitting.after_fit --law corner     # hours on two cores
    python -m pedmesh.fitting.after_fit --list           # the steps and what they write
    python -m pedmesh.fitting.after_fit --from validate  # again from a step on

Options: ``--law`` (the fit whose best point becomes the preset; default ``exits``, the
shipped fit's), ``--only NAME,...``, ``--from NAME`` (drops the marks of that step and
those after it), ``--logs DIR`` (default ``runs/after_fit``), ``--dry-run`` (prints the
commands). The chain stops at the first step that fails; its log names why.

To see what a candidate point would do before making it the preset (e.g. to eos), run the
first steps in a worktree of their own, where they write its pedmesh/data and not this
checkout's (each step reads and writes the checkout it runs from; the worktree compiles
its kernels once, some minutes)::

    git worktree add /tmp/preview HEAD
    cd /tmp/preview && cp <this checkout>/docs/validation/fit_evaluations_<law>.csv \
        docs/validation/
    PYTHONPATH=/tmp/preview python -m pedmesh.fitting.after_fit --law <law> \
        --only preset,law,eos,eos_door

(Patching the data directory of an imported module instead is how a preview once wrote
its table into the shipped pedmesh/data: ``runpy`` runs a module afresh.)

What it cannot do for you: ``eos_door`` and ``hybrid`` print their figures, which
``docs/validation/dense_crowds.md`` and ``docs/models.md`` quote by hand (their logs keep
them), and the regression values
(``PINNED`` in ``tests/sfm/test_regression_values.py``) are the new
``docs/data/convergence.json``'s seed-0 times on uo-100 at the default mesh: the last
step prints both for you to copy.
"""

from __future__ import annotations

import argparse
import datetime
import json
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class Step:
    """One step: its name, what it does and writes, and its command (run from ROOT)."""

    name: str
    what: str
    argv: tuple[str, ...]


def steps(law: str) -> list[Step]:
    """The chain after the fit ``law``, in order."""
    py = sys.executable
    validate = (py, "-m", "pedmesh.fitting.validate", "--preset", "validated")
    return [
        Step("preset", "the fit's best point as the preset: pedmesh/data/validated.json, "
                       "docs/validation/fit.md",
             (py, "-m", "pedmesh.fitting.fit_validated", "--law", law, "--report-only")),
        Step("law", "the continuum models' table, measured from the social force model: "
                    "pedmesh/data/fd_validated.json",
             (py, "-m", "pedmesh.fitting.continuum_law")),
        Step("eos", "eos's equation of state under the preset: pedmesh/data/eos_validated.json",
             (py, "-m", "pedmesh", "calibrate", "--preset", "validated", "-o",
              "pedmesh/data/eos_validated.json")),
        Step("convergence", "T50/T90 against the mesh (the preset's runs again): "
                            "docs/data/convergence.json, docs/images/convergence.png",
             (py, "benchmarks/convergence.py", "--json", "docs/data/convergence.json",
              "--rooms", "uo-100,example2,door", "--models",
              "sfm-validated,sfm-paper,sfm-weidmann,eos,rdue,pw",
              "--plot", "docs/images/convergence.png")),
        Step("doors", "the door probes: docs/data/door_probes.json, "
                      "docs/validation/door_probes.md",
             (py, "benchmarks/door_physics.py", "--probes", "validated")),
        Step("validate", "the validation tables, six seeds: docs/validation/validated/",
             (*validate, "--entrance", "replay", "--bottleneck", "--walldoor", "--free",
              "--seeds", "1,2,3,4,5,6", "--out", "docs/validation/validated")),
        Step("validate_door", "the corridors with the entrance as a door: "
                              "docs/validation/validated_door/",
             (*validate, "--entrance", "door", "--seeds", "1,2,3,4,5,6", "--out",
              "docs/validation/validated_door")),
        Step("exit_ghosts", "people beyond the exits, eos against the SFM: "
                            "docs/data/exit_ghosts.json",
             (py, "benchmarks/exit_ghosts.py")),
        Step("eos_door", "eos against the SFM on Example 2, the bottleneck and the venue "
                         "(printed: docs/validation/dense_crowds.md quotes it)",
             (py, "benchmarks/eos_door.py", "--times", "--seeds", "2")),
        Step("hybrid", "the hybrid prototype against both models on the corridor "
                       "bottleneck (printed: docs/models.md quotes it)",
             (py, "benchmarks/hybrid.py")),
        Step("rimea", "the RiMEA tests: examples/rimea/RIMEA.md",
             (py, "examples/rimea/rimea.py")),
        Step("figures", "the docs' tables from the benchmarks' JSON: docs/_generated/",
             (py, "docs/render_figures.py")),
    ]


def pinned_note() -> str:
    """The regression values a refit moves, from the new convergence study."""
    path = ROOT / "docs" / "data" / "convergence.json"
    runs = json.loads(path.read_text())["results"]["runs"]
    got = {}
    for preset in ("validated", "weidmann"):
        r = runs.get(f"uo-100|sfm-{preset}|default|0|None")
        if r:
            got[preset] = (round(r["T50"], 2), round(r["T90"], 2))
    return ("PINNED of tests/sfm/test_regression_values.py, from " + path.name + ": "
            + json.dumps(got))


def _mark(logs: Path, step: Step) -> Path:
    return logs / f"{step.name}.done"


def run_chain(chain: list[Step], logs: Path, dry_run: bool = False) -> int:
    """Run the steps of ``chain`` not marked done in ``logs``; 0, or the failed step's exit
    code."""
    logs.mkdir(parents=True, exist_ok=True)
    for i, step in enumerate(chain, start=1):
        head = f"[{i}/{len(chain)}] {step.name}"
        if _mark(logs, step).is_file():
            print(f"{head}: done before ({_mark(logs, step).read_text().strip()})", flush=True)
            continue
        print(f"{head}: {step.what}\n    {' '.join(step.argv)}", flush=True)
        if dry_run:
            continue
        log = logs / f"{step.name}.log"
        t0 = time.perf_counter()
        with log.open("w") as fh:
            rc = subprocess.run(step.argv, cwd=ROOT, stdout=fh, stderr=subprocess.STDOUT).returncode
        took = time.perf_counter() - t0
        if rc != 0:
            print(f"{head} FAILED (exit code {rc}) after {took / 60:.1f} min; see {log}",
                  flush=True)
            return rc
        stamp = datetime.datetime.now().isoformat(timespec="seconds")
        _mark(logs, step).write_text(f"{stamp}, {took / 60:.1f} min\n")
        print(f"{head}: done in {took / 60:.1f} min (log {log})", flush=True)
    if not dry_run:
        print(pinned_note(), flush=True)
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pedmesh.fitting.after_fit",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--law", default="exits", help="the fit whose best point becomes the preset")
    ap.add_argument("--list", action="store_true", help="list the steps and stop")
    ap.add_argument("--only", default=None, metavar="NAME,...", help="run these steps only")
    ap.add_argument("--from", dest="start", default=None, metavar="NAME",
                    help="run again from this step on (its marks and those after it dropped)")
    ap.add_argument("--logs", type=Path, default=ROOT / "runs" / "after_fit",
                    help="logs and done-marks (default runs/after_fit)")
    ap.add_argument("--dry-run", action="store_true", help="print the commands only")
    args = ap.parse_args(argv)
    chain = steps(args.law)
    names = [s.name for s in chain]
    if args.list:
        for s in chain:
            print(f"{s.name:14s} {s.what}")
        return 0
    for name in ([args.start] if args.start else []) + (args.only.split(",") if args.only
                                                        else []):
        if name not in names:
            ap.error(f"unknown step {name!r} (steps: {', '.join(names)})")
    if args.start:
        for s in chain[names.index(args.start):]:
            _mark(args.logs, s).unlink(missing_ok=True)
    if args.only:
        keep = set(args.only.split(","))
        chain = [s for s in chain if s.name in keep]
    return run_chain(chain, args.logs, args.dry_run)


if __name__ == "__main__":
    sys.exit(main())
