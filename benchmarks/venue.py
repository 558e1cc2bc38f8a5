"""Venue scale: the continuum model against the social force model on a 100,000-person
exhibition centre (geometries/venue.json, 58,800 m^2, 11 exits).

1. ``pedmesh run geometries/venue.json --model eos`` as a user runs it (a new process, with
   its progress bar on stderr): wall time, peak memory (the child's maximum resident set),
   T50/T90/T100.
2. The SFM on the same venue cannot finish here in reasonable time, so its cost per
   simulated second is measured as the difference of two short runs (``--t-end`` T1 and T2,
   so that start-up cancels) and its full evacuation is extrapolated: start-up + rate x
   T100, with T100 the SFM's own on the 10,000-person venue scaled by the ratio of eos's
   T100 on the two venues (the SFM evacuates the full venue no faster than eos predicts;
   the eos T100 of the full venue is used as the lower bound too). Peak memory of the
   longer short run is reported.
3. Both models on geometries/venue_10k.json (the same venue, a tenth of the crowd), to the
   end: T50 and T90 of eos against the SFM.

    python benchmarks/venue.py                 # all three parts (about an hour on 2 cores)
    python benchmarks/venue.py --skip-10k      # parts 1 and 2
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run(room: str, model: str, out: Path, *extra: str) -> tuple[float, float, dict]:
    """(wall [s], peak memory [MB], summary) of ``pedmesh run`` in a new process."""
    cmd = [sys.executable, "-c",
           "import resource, subprocess, sys; "
           "r = subprocess.run(sys.argv[1:]).returncode; "
           "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr); "
           "sys.exit(r)",
           sys.executable, "-m", "pedmesh", "run", room, "--model", model, "--out", str(out),
           *extra]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                       text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        sys.exit(f"pedmesh run {room} --model {model} failed:\n{p.stderr[-2000:]}")
    peak_mb = int(p.stderr.strip().splitlines()[-1]) / 1024.0  # (Linux: KiB)
    return wall, peak_mb, json.loads((out / "summary.json").read_text())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--short", type=float, nargs=2, default=(5.0, 15.0), metavar=("T1", "T2"),
                   help="the SFM's two short runs [s] (default 5 15)")
    p.add_argument("--skip-10k", action="store_true")
    args = p.parse_args()
    venue, small = "geometries/venue.json", "geometries/venue_10k.json"
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        print("eos, full venue ...", flush=True)
        w_eos, m_eos, s_eos = run(venue, "eos", tmp / "eos", "-q")
        print(f"  eos: {s_eos['n_evacuated']:,.0f} of {s_eos['n_initial']:,.0f} out, T50 "
              f"{s_eos['t_evac_50']:.1f} s, T90 {s_eos['t_evac_90']:.1f} s, T100 "
              f"{s_eos['t_evac_100']:.1f} s; {s_eos['mesh']['triangles']:,} triangles, "
              f"{s_eos['steps']:,} steps; wall {w_eos:.0f} s, peak memory {m_eos:.0f} MB",
              flush=True)
        t1, t2 = args.short
        w1, _, _ = run(venue, "sfm", tmp / "sfm1", "-q", "--t-end", str(t1))
        w2, m_sfm, s2 = run(venue, "sfm", tmp / "sfm2", "-q", "--t-end", str(t2))
        rate = (w2 - w1) / (t2 - t1)
        setup = w1 - rate * t1
        print(f"  sfm: {t1:g} s in {w1:.0f} s, {t2:g} s in {w2:.0f} s: {rate:.2f} s of wall "
              f"time per simulated second, start-up {setup:.0f} s; peak memory {m_sfm:.0f} MB",
              flush=True)
        t100 = s_eos["t_evac_100"]
        ratio_note = "the eos T100 of the venue"
        if not args.skip_10k:
            print("both models, 10,000-person venue ...", flush=True)
            w_e10, m_e10, e10 = run(small, "eos", tmp / "eos10", "-q")
            w_s10, m_s10, s10 = run(small, "sfm", tmp / "sfm10", "-q")
            print(f"\n{small}: {s10['n_initial']:,} people")
            print(f"{'model':>6} {'T50':>8} {'T90':>8} {'T100':>8} {'wall':>8} {'memory':>8}")
            for name, s, w, m in (("sfm", s10, w_s10, m_s10), ("eos", e10, w_e10, m_e10)):
                print(f"{name:>6} {s['t_evac_50']:>8.1f} {s['t_evac_90']:>8.1f} "
                      f"{s['t_evac_100'] or float('nan'):>8.1f} {w:>8.0f} {m:>7.0f}M")
            d50 = 100 * (e10["t_evac_50"] / s10["t_evac_50"] - 1)
            d90 = 100 * (e10["t_evac_90"] / s10["t_evac_90"] - 1)
            print(f"eos against the SFM: T50 {d50:+.1f} %, T90 {d90:+.1f} %; wall "
                  f"{w_e10 / w_s10:.3f}x")
            if s10["t_evac_100"] and e10["t_evac_100"]:
                t100 = max(t100, s10["t_evac_100"] * s_eos["t_evac_100"] / e10["t_evac_100"])
                ratio_note = ("the SFM's T100 of the 10,000-person venue times the ratio of "
                              "eos's T100 on the two venues (and at least eos's own)")
        sfm_full = setup + rate * t100
        print(f"\nSFM full evacuation extrapolated to T100 = {t100:.0f} s ({ratio_note}): "
              f"{sfm_full:,.0f} s = {sfm_full / 3600:.1f} h")
        print(f"eos full evacuation: {w_eos:,.0f} s = {w_eos / sfm_full:.3f}x the SFM; peak "
              f"memory eos {m_eos:.0f} MB, SFM {m_sfm:.0f} MB")


if __name__ == "__main__":
    main()
