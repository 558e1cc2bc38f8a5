"""Every script in examples/ runs at a small size, in a subprocess with a temporary folder.

Each script runs with the options its docstring gives for a small run. It must exit with
status 0 and write its main output into the temporary folder, never into the repository.
The whole file takes about 30 s on two cores once numba's kernels are cached, and
80 s from an empty cache.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import pedmesh

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
GEOMETRIES = ROOT / "geometries"

#: script (relative to examples/) -> (its arguments for a small run, with {tmp} the
#: temporary folder; the files it must write, relative to {tmp})
SMALL_RUNS: dict[str, tuple[list[str], list[str]]] = {
    "reproduce_paper.py": (
        ["--quick", "--small", "--out", "{tmp}"],
        ["RESULTS.md", "rooms/example2.json", "fig_f4_evacuation.png",
         "fig_f5_sfm_snapshots.png", "fig_f6_density_example2.png",
         "fig_f7_density_example3.png", "fig_f8_outflow.png", "fig_f9_fundamental.png"]),
    "eos_flowing_check.py": (
        ["--geometry", str(GEOMETRIES / "corridor_bottleneck.json"), "--out", "{tmp}"],
        ["eos_flowing_check.md", "eos_flowing_check.png"]),
    "door_width_study.py": (
        ["--members", "2", "--widths", "1.2,2.4", "--workers", "1", "--out", "{tmp}/runs",
         "--results", "{tmp}"],
        ["door_width.md", "door_width_bands.png", "room-1.2m.json", "room-2.4m.json"]),
    "rimea/rimea.py": (
        ["--tests", "1,2,6", "--models", "sfm,rdue", "--out", "{tmp}/runs", "--rooms",
         "{tmp}/rooms", "--report", "{tmp}/RIMEA.md"],
        ["RIMEA.md", "runs/rimea.json", "rooms/rimea-06-corner.json",
         "rooms/rimea-02-stair-up.json"]),
    "venue/make_venue.py": (
        ["--out", "{tmp}"],
        ["venue.json", "venue_10k.json"]),
}


def _scripts() -> set[str]:
    """The runnable scripts in examples/ (those with a ``__main__`` block)."""
    return {p.relative_to(EXAMPLES).as_posix() for p in EXAMPLES.rglob("*.py")
            if "__main__" in p.read_text(encoding="utf-8")}


def _repo_state() -> set[str] | None:
    """The repository's changed, untracked and ignored paths (numba's and Python's caches
    left out), or None outside a git checkout."""
    r = subprocess.run(["git", "status", "--porcelain", "--ignored"], cwd=ROOT,
                       capture_output=True, text=True)
    if r.returncode != 0:
        return None
    return {line for line in r.stdout.splitlines()
            if "__pycache__" not in line and not line.endswith(".pyc")}


def _run(script: str, args: list[str], tmp: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, MPLBACKEND="Agg")
    # the pedmesh these tests import, whatever is installed
    env["PYTHONPATH"] = os.pathsep.join(
        [str(Path(pedmesh.__file__).resolve().parents[1])]
        + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    return subprocess.run([sys.executable, str(EXAMPLES / script),
                           *(a.format(tmp=tmp) for a in args)],
                          cwd=tmp, env=env, capture_output=True, text=True, timeout=900)


def test_every_example_has_a_small_run():
    assert _scripts() == set(SMALL_RUNS)


@pytest.mark.parametrize("script", sorted(SMALL_RUNS))
def test_example_runs_small(script, tmp_path):
    if script == "door_width_study.py":
        pytest.importorskip("distributed")
    args, outputs = SMALL_RUNS[script]
    before = _repo_state()
    r = _run(script, args, tmp_path)
    assert r.returncode == 0, (f"{script} exited with {r.returncode}\n--- stdout\n"
                               f"{r.stdout[-3000:]}\n--- stderr\n{r.stderr[-5000:]}")
    missing = [f for f in outputs if not (tmp_path / f).is_file()]
    assert missing == [], f"{script} did not write {missing}"
    if before is not None:
        assert _repo_state() == before, f"{script} wrote into the repository"


def test_make_venue_writes_the_shipped_venues(tmp_path):
    """The venue script makes exactly the two venues in geometries/."""
    r = _run("venue/make_venue.py", ["--out", "{tmp}"], tmp_path)
    assert r.returncode == 0, r.stderr
    for name in ("venue.json", "venue_10k.json"):
        assert (tmp_path / name).read_bytes() == (GEOMETRIES / name).read_bytes()
