"""The continuum models' desired-speed law under a preset: the social force model's own
fundamental diagram, measured.

The social force model evaluates its desired speed U_e at a Gaussian kernel density
without a pedestrian's own share (``density_self=0``), which reads lower than the crowd's
true density (nobody stands within a body diameter of anyone, lanes form, walls cut the
kernel). A continuum model's density is the true one. So that both models share one
fundamental diagram, the continuum models take as their law ``U_e(rho) = U_f g(rho)`` the
speed the social force model actually walks at the density rho, measured by
:func:`pedmesh.calibration.measure_fundamental_diagram` (its protocol,
``pedmesh.calibration.FD_PROTOCOL``: a 40 x 10 m corridor filled over 30 m at the start
densities 0.25 ... 9 /m^2, ``--seeds`` realisations each, the density and speed in a box
2 m from the walls at t 3-6 s) and made a table by ``fd_speed_table`` (the seeds' means,
never faster when denser, 0:1 in front, a jam point extrapolated from the last two).

Writes ``pedmesh/data/fd_<preset>.json`` (the table as ``speed_table`` text, every
measurement, the protocol, the SFM parameters) unless ``--no-write``; the preset
(:mod:`pedmesh.presets`) gives it to the continuum models as their ``speed_table``.

    python -m pedmesh.fitting.continuum_law [--preset validated] [--seeds 2] [--no-write]

About 2 minutes on two cores.
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
import time
from pathlib import Path

#: pedmesh/ (the package whose data/ the table is written into)
PACKAGE = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pedmesh.fitting.continuum_law",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--preset", default="validated")
    ap.add_argument("--seeds", type=int, default=2, help="realisations per density (2)")
    ap.add_argument("--no-write", action="store_true", help="print, write nothing")
    args = ap.parse_args(argv)
    from pedmesh._version import __version__
    from pedmesh.calibration import (FD_BOX, FD_DENSITIES, FD_FILLED, FD_JAM_CAP, FD_LENGTH,
                                     FD_WIDTH, FD_WINDOW, fd_speed_table,
                                     measure_fundamental_diagram)
    from pedmesh.presets import preset_overrides
    from pedmesh.models import get_model
    from pedmesh.speed import format_speed_table

    sfm = preset_overrides(args.preset, get_model("sfm").parameter_names, {})
    U_f = float(sfm.get("U_f", 1.034))
    print(f"The SFM's fundamental diagram under preset {args.preset} (U_f {U_f:g} m/s), "
          f"{args.seeds} realisation(s) per density")
    t0 = time.perf_counter()
    rows = measure_fundamental_diagram(args.preset, args.seeds, log=print)
    table = fd_speed_table(rows, U_f)
    text = format_speed_table(table)
    print(f"\ncontinuum speed_table: {text}\n(wall {time.perf_counter() - t0:.0f} s)")
    print(" rho [/m^2]   v [m/s]   g = v/U_f")
    for rho, g in table:
        print(f"  {rho:8.3f}  {g * U_f:8.3f}  {g:8.4f}")
    if args.no_write:
        return 0
    path = PACKAGE / "data" / f"fd_{args.preset}.json"
    record = {
        "speed_table": text, "U_f": U_f,
        "measurements": rows,
        "protocol": {"corridor_m": [FD_LENGTH, FD_WIDTH], "filled_to_x_m": FD_FILLED,
                     "box_m": FD_BOX, "window_s": FD_WINDOW, "densities": FD_DENSITIES,
                     "seeds": args.seeds, "jam_cap": FD_JAM_CAP,
                     "script": "python -m pedmesh.fitting.continuum_law",
                     "functions": "pedmesh.calibration.measure_fundamental_diagram, "
                                  "fd_speed_table"},
        "sfm_parameters": {k: v for k, v in sfm.items() if k != "calibration"},
        "date": datetime.date.today().isoformat(), "pedmesh_version": __version__,
    }
    path.write_text(json.dumps(record, indent=1) + "\n")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
