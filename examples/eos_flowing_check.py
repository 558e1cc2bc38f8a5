"""Does the equilibrium equation of state hold in a flowing crowd?

    python examples/eos_flowing_check.py [--geometry geometries/example2.json] [--out DIR]

Runs the social force model on the room (default: the paper's Example 2), records every
second the per-pedestrian virial stress (pair forces with the simulator's kernel, plus the
velocity fluctuation about the kernel-averaged velocity), bins it by the kernel density at
each pedestrian, and compares the flowing crowd's pressure with the law measured in
periodic boxes at rest (``pedmesh calibrate``, the shipped calibration). Also reports the
deviatoric part in the walking frame. Writes ``eos_flowing_check.md`` and ``.png`` into
``--out`` (default: ``examples/results/``).

A small run (seconds once numba has compiled; ``tests/test_examples.py``): the 150 people
of the corridor bottleneck instead of Example 2's 2400, into a folder of one's own::

    python examples/eos_flowing_check.py --geometry geometries/corridor_bottleneck.json --out DIR
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from pedmesh.mesh import triangulate

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> None:
    from pedmesh import load_room
    from pedmesh.calibration import flowing_stress, load_eos
    from pedmesh.plotting import _plt

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--geometry", default=str(ROOT / "geometries" / "example2.json"))
    ap.add_argument("--out", default=str(ROOT / "examples" / "results"))
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    room = load_room(a.geometry)
    mesh = triangulate(room)
    t0 = time.perf_counter()
    r = flowing_stress(mesh, progress=True)
    wall = time.perf_counter() - t0
    cal = load_eos()
    lines = [f"# Equation of state in the flowing crowd ({room.name})", "",
             "Social force run of the room with the default parameters; every second each "
             "pedestrian's virial stress S_i (pair forces / m, half per partner, plus the "
             "velocity fluctuation about the kernel velocity) is binned by the kernel density "
             "at the pedestrian. p = <rho_i tr S_i / 2>; p_eos is the shipped calibration "
             "(periodic boxes at rest). normal difference = (S_ee - S_nn)/2 and shear = |S_en| of "
             "the bin-mean tensor in the walking frame, relative to the pressure; individual = "
             "mean size of single pedestrians' deviators relative to their mean pressure.", "",
             f"SFM run and sampling: {wall:.0f} s wall.", "",
             "| density bin [ped/m^2] | samples | mean rho | p flowing | p virial | p_eos (rest) "
             "| flowing / rest | normal diff | shear | individual dev |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    edges = np.arange(0.0, 8.01, 0.5)
    for k in range(len(r["rho"])):
        if r["count"][k] < 20:
            continue
        ratio = r["p"][k] / r["p_eos"][k] if r["p_eos"][k] > 0 else float("nan")
        lines.append(
            f"| {edges[k]:.1f}-{edges[k + 1]:.1f} | {int(r['count'][k])} | {r['rho'][k]:.2f} | "
            f"{r['p'][k]:.3g} | {r['p_virial'][k]:.3g} | {r['p_eos'][k]:.3g} | {ratio:.2f} | "
            f"{r['normal_diff'][k]:+.2f} | {r['shear'][k]:.2f} | {r['dev_individual'][k]:.2f} |")
    text = "\n".join(lines) + "\n"
    (out / "eos_flowing_check.md").write_text(text, encoding="utf-8")
    print(text)
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 4))
    ok = r["count"] >= 20
    name = "Example 2" if room.name == "example2" else room.name
    ax.semilogy(r["rho"][ok], r["p"][ok], "o", label=f"flowing crowd ({name}), binned")
    tab = cal["table"]
    rr = np.array([t["rho"] for t in tab])
    ax.errorbar(rr, [t["p"] for t in tab], yerr=[t["p_err"] for t in tab], fmt="s", ms=4,
                label="periodic boxes at rest (calibration)")
    g = np.linspace(0.3, 12, 300)
    from pedmesh.calibration import eos_pressure

    ax.semilogy(g, eos_pressure(g, cal), "-", lw=1, label="fitted p(rho)")
    ax.semilogy(g, 0.5 * cal["gamma1"] * g**2, "--", lw=1, label="mean field gamma1 rho^2/2")
    ax.set_xlabel("density [ped/m^2]")
    ax.set_ylabel("pressure per unit mass [ped/s^2]")
    ax.set_ylim(1e-5, 1e3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "eos_flowing_check.png", dpi=120)
    print(f"wrote {out / 'eos_flowing_check.md'} and .png")


if __name__ == "__main__":
    main()
