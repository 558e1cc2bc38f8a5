"""An exit as a line, as a door with room beyond it, and with people beyond it (issue 44).

Under the ``validated`` preset the social force model's people read their speed law at the
kernel density of the crowd ahead of them (``density_cone``). Removed at the exit line,
those who leave vanish from that density: the front of the queue reads empty space and
walks out faster than through a door with the world beyond it. ``exit_ghosts=1`` keeps
them in the density of those behind while they walk on (``pedmesh.models.sfm.kernels``:
``walk_ghosts``, ``ghost_density``).

Three ways of Example 2's 10 m exit (x = 100 m, y in [20, 30] m), the social force model
under ``validated`` with ``exit_ghosts`` set as given:

* **line**: the exit line itself, people removed on it (``exit_ghosts=0``);
* **porch**: the exit as a door in a 0.2 m wall onto a 10 x 30 m porch whose far side is
  the exit: people walk on through real space (``exit_ghosts=0``);
* **ghosts**: the exit line, people beyond it in the density (``exit_ghosts=1``);

and eos (the shipped preset) on the room. Measured: the flow through x = 100 m between the
10th and the 90th percentile of the crossings (trajectories at the run's frame rate), the
room's T50/T90 (for the porch: the crossings of x = 100 m, so that the 10 m walk beyond
does not count), each at ``--seeds``. The published specific flow of wide openings is
about 1.9-2.4 /(m s) (``pedmesh/data/bottleneck_literature.json``: b >= 1.8 m).

    python benchmarks/exit_ghosts.py [--seeds 0,1] [--json FILE]   # ~15 min on 2 cores

``docs/render_figures.py`` renders the table of ``docs/validation/exit_ghosts.md`` from the
JSON.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
ROOM = ROOT / "geometries" / "example2.json"
#: [m] the exit line's x
X_EXIT = 100.0
#: [m] the exit's width
WIDTH = 10.0
#: (name, porch, exit_ghosts, what it is)
CASES = (("line", False, 0, "exit line, people removed on it"),
         ("porch", True, 0, "door in a 0.2 m wall onto a 10 x 30 m porch"),
         ("ghosts", False, 1, "exit line, people beyond it in the density (exit_ghosts=1)"))


def porch_room(tmp: Path) -> Path:
    """Example 2 with its exit as a door in a 0.2 m wall onto a 10 x 30 m porch."""
    room = json.loads(ROOM.read_text())
    room["name"] = "example2-porch"
    room["outline"] = [[0, 0], [100, 0], [100, 20], [100.2, 20], [100.2, 10], [110, 10],
                       [110, 40], [100.2, 40], [100.2, 30], [100, 30], [100, 50], [0, 50]]
    room["exits"] = [{"name": "exit", "polyline": [[110, 10], [110, 40]]}]
    path = tmp / "example2_porch.json"
    path.write_text(json.dumps(room))
    return path


def crossings(res, x_line: float = X_EXIT) -> np.ndarray:
    """Sorted times [s] at which each person first stood at x >= ``x_line`` in the
    trajectories."""
    tr = res.trajectories
    at = tr["x"] >= x_line
    ids, t = tr["id"][at], tr["frame"][at] / res.frame_rate
    order = np.lexsort((t, ids))
    ids, t = ids[order], t[order]
    first = np.ones(len(ids), bool)
    first[1:] = ids[1:] != ids[:-1]
    return np.sort(t[first])


def flow(c: np.ndarray) -> float:
    """People per second between the 10th and the 90th percentile of crossings ``c``."""
    n = len(c)
    return 0.8 * n / float(c[int(0.9 * n) - 1] - c[int(0.1 * n)])


def quantile_time(c: np.ndarray, n0: int, q: float) -> float:
    """When the ``q`` share of ``n0`` people had crossed."""
    k = int(np.ceil(q * n0)) - 1
    return float(c[k]) if k < len(c) else float("nan")


def run_case(name: str, porch: bool, ghosts: int, seed: int, tmp: Path) -> dict:
    import pedmesh

    room = porch_room(tmp) if porch else ROOM
    t0 = time.perf_counter()
    res = pedmesh.simulate(str(room), "sfm", preset="validated", seed=seed,
                           params={"exit_ghosts": ghosts}, quiet=True)
    c = crossings(res)
    n0 = int(res.summary["n_initial"])
    return {"case": name, "seed": seed, "n": n0, "crossed": int(len(c)),
            "flow_per_s": flow(c), "flow_per_m_s": flow(c) / WIDTH,
            "T50_s": quantile_time(c, n0, 0.5), "T90_s": quantile_time(c, n0, 0.9),
            "wall_s": time.perf_counter() - t0}


def run_eos() -> dict:
    import pedmesh

    res = pedmesh.simulate(str(ROOM), "eos", preset="validated", quiet=True)
    t, out = (np.asarray(a, float) for a in res.evacuation)
    n0 = float(res.summary["n_initial"])
    a, b = np.interp([0.1 * n0, 0.9 * n0], out, t)
    return {"case": "eos", "seed": None, "T50_s": float(res.times["T50"]),
            "T90_s": float(res.times["T90"]), "flow_per_s": 0.8 * n0 / (b - a),
            "flow_per_m_s": 0.8 * n0 / (b - a) / WIDTH}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--json", type=Path, default=ROOT / "docs" / "data" / "exit_ghosts.json")
    args = ap.parse_args(argv)
    seeds = [int(s) for s in args.seeds.split(",")]
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from _common import write_json

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in seeds:  # the cases interleaved, a seed at a time
            for name, porch, ghosts, _ in CASES:
                rows.append(run_case(name, porch, ghosts, seed, Path(tmp)))
                r = rows[-1]
                print(f"{name:7s} seed {seed}: {r['flow_per_m_s']:.2f} /(m s), T50 "
                      f"{r['T50_s']:.1f} s, T90 {r['T90_s']:.1f} s ({r['wall_s']:.0f} s)",
                      flush=True)
    rows.append(run_eos())
    write_json(args.json, {"room": "geometries/example2.json", "seeds": seeds, "rows": rows})
    e = rows[-1]
    print(f"eos: {e['flow_per_m_s']:.2f} /(m s), T50 {e['T50_s']:.1f} s, T90 {e['T90_s']:.1f} s"
          " (docs/render_figures.py renders the table of its JSON)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
