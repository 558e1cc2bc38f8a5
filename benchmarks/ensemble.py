"""Ensemble benchmark: members on two Dask workers against the same members one after
another in this process.

    python benchmarks/ensemble.py [--room geometries/example3.json] [--members 8]
                                  [--t-end 20] [--repeats 2]

Both sides run the same members (same seeds, the SFM, the same room) to the same t_end,
and both are timed whole, start-up included: the sequential side is a new Python process
that imports pedmesh, meshes the room and runs the members one after another; the parallel
side is a ``pedmesh.ensemble(..., workers=2)`` call, which starts a LocalCluster whose two
worker processes import pedmesh and mesh the room. Numba's compiled kernels come from its
disk cache on both sides (a first call here fills it). The sides alternate, each
``--repeats`` times, into fresh folders; the script prints every time, the median and
best of each side and their ratio.

Goal (issue 20): 8 members of a small room on 2 workers take at most 0.6 x the sequential
wall time.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--room", default=str(ROOT / "geometries" / "example3.json"))
    ap.add_argument("--members", type=int, default=8)
    ap.add_argument("--t-end", type=float, default=20.0)
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args()

    from pedmesh.ensembles import ensemble

    room = str(Path(args.room).resolve())
    mesh_options = {"max_area": 0.5, "min_angle": 30.0, "exit_size": None}
    work = Path(tempfile.mkdtemp(prefix="pedmesh-bench-ens-"))

    def sequential(k: int) -> float:
        code = (
            "import sys\n"
            "from pathlib import Path\n"
            "from pedmesh.ensembles import plan_members, run_member\n"
            f"room, out, t_end, n = {room!r}, Path({str(work / f'seq{k}')!r}), "
            f"{args.t_end!r}, {args.members!r}\n"
            f"mesh_options = {mesh_options!r}\n"
            "plan = plan_members(room, 'sfm', n, out, overrides={}, sweep={}, seed=0,\n"
            "                    t_end=t_end, mesh_options=mesh_options, preset=None,\n"
            "                    seeded=True)\n"
            "for m in plan:\n"
            "    row = run_member({'member': m.member, 'point': 0, 'seed': m.seed,\n"
            "                      'values': {}, 'geometry': room, 'model': 'sfm',\n"
            "                      'overrides': {}, 't_end': t_end, 'out_dir': str(m.out_dir),\n"
            "                      'mesh_options': mesh_options, 'preset': None,\n"
            "                      'model_options': {'seed': m.seed}})\n"
            "    if row['status'] not in ('finished', 'stopped at t_end'):\n"
            "        sys.exit(f'member failed: {row}')\n"
        )
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c", code], check=True)
        return time.perf_counter() - t0

    def parallel(k: int) -> float:
        t0 = time.perf_counter()
        df = ensemble(room, "sfm", args.members, work / f"par{k}", workers=2,
                      t_end=args.t_end, quiet=True)
        assert set(df["status"]) <= {"finished", "stopped at t_end"}, df
        return time.perf_counter() - t0

    sequential(-1)  # fills numba's disk cache if it is empty
    seq, par = [], []
    for k in range(args.repeats):
        seq.append(sequential(k))
        par.append(parallel(k))
        print(f"repeat {k + 1}: sequential {seq[-1]:.1f} s, 2 workers {par[-1]:.1f} s",
              flush=True)
    ms, mp = statistics.median(seq), statistics.median(par)
    print(f"\n{args.members} members of {Path(room).name} to t = {args.t_end:g} s")
    print(f"sequential (one process):  median {ms:.1f} s, best {min(seq):.1f} s")
    print(f"ensemble on 2 workers:     median {mp:.1f} s, best {min(par):.1f} s")
    ratio = mp / ms
    print(f"ratio 2 workers / sequential: median {ratio:.2f}, best-to-best "
          f"{min(par) / min(seq):.2f} (goal <= 0.6: {'met' if ratio <= 0.6 else 'NOT met'})")
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
