"""``pedmesh calibrate``: measure the social force model's equation of state."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = "measure the social force model's equation of state p(rho) for the eos model"
DESCRIPTION = """\
Measure the pressure per unit mass of the social force model,

  P = 1/(2|A|) sum_{i<j} r_ij . f_ij / m  +  1/(2|A|) sum_i |v_i|^2,

in periodic boxes of standing, relaxed crowds at densities from 0.5 to 12 ped/m^2, with the
simulator's own pair force; fit a smooth monotone p(rho); write a calibration file for the
continuum model 'eos' (use it with: pedmesh run ROOM --model eos --param calibration=FILE).
The file keeps every measured density as it goes, so an interrupted run loses nothing
(it is marked incomplete and the eos model refuses it).

Takes 2-3 minutes with the defaults. The mean-field pressure gamma1 rho^2 / 2 of mac1/mac2
is printed beside the measurement: pedestrians keep apart, so the measured pressure is
smaller by orders of magnitude at low density.

examples:
  pedmesh calibrate -o eos.json
  pedmesh calibrate --param A=1500 --param B=0.1 -o eos-soft.json
  pedmesh calibrate --preset weidmann -o eos-weidmann.json
  pedmesh calibrate --densities 1,2,4,8 --replicas 2 -o quick.json
"""


def add_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="a social force parameter (A, B, k, kappa, m, r, tau; repeatable)")
    p.add_argument("--preset", default=None, metavar="NAME",
                   help="the social force parameters of this preset (default: paper; see "
                        "`pedmesh presets`), --param on top")
    p.add_argument("-o", "--out", default="eos.json", metavar="FILE",
                   help="calibration file to write (default: eos.json)")
    p.add_argument("--densities", default=None, metavar="R1,R2,...",
                   help="densities [ped/m^2] to measure (default: 0.5,1,...,12)")
    p.add_argument("--n", type=int, default=None, help="pedestrians per box (default: 300)")
    p.add_argument("--replicas", type=int, default=None,
                   help="independent boxes per density, for the error (default: 3)")
    p.add_argument("--relax-time", type=float, default=None, metavar="T",
                   help="relaxation before sampling [s] (default: 6)")
    p.add_argument("--sample-time", type=float, default=None, metavar="T",
                   help="averaging time [s] (default: 6)")
    p.add_argument("--dt", type=float, default=None, help="time step [s] (default: 0.002)")
    p.add_argument("--noise", type=float, default=None,
                   help="velocity noise [m/s per sqrt(s)] (default: 0, crowds at rest)")
    p.add_argument("--seed", type=int, default=None, help="random seed (default: 0)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or table")


def run(args: argparse.Namespace) -> int:
    from ..calibration import CalibrationOptions, calibrate, save_eos
    from ..errors import ParameterError
    from ..models.sfm.params import SocialForceParams, with_overrides
    from ..parameters import parse_overrides
    from .._signals import stop_on_signals

    overrides = parse_overrides(args.param)
    # the pair forces, and what sets the social radii of the dense-crowd terms
    allowed = {"A", "B", "k", "kappa", "m", "r", "tau", "shrink", "t_space", "crowd_stretch",
               "crowd_knee", "U_f", "R", "speed_law", "speed_table", "density_self", "beta",
               "rho_jam", "gamma_w"}
    bad = sorted(set(overrides) - allowed)
    if bad:
        raise ParameterError(f"unknown or irrelevant parameter '{bad[0]}' for a calibration "
                             f"(known: {', '.join(sorted(allowed))})")
    from ..presets import DEFAULT_PRESET, get_preset

    base = get_preset(args.preset or DEFAULT_PRESET).overrides(allowed)
    (params,) = with_overrides({**base, **overrides}, SocialForceParams())
    opts = {}
    if args.densities:
        try:
            opts["densities"] = tuple(float(x) for x in args.densities.split(",") if x.strip())
        except ValueError:
            raise ParameterError(f"--densities expects numbers, got '{args.densities}'") from None
    for name in ("n", "replicas", "relax_time", "sample_time", "dt", "noise", "seed"):
        v = getattr(args, name)
        if v is not None:
            opts[name] = v
    options = CalibrationOptions(**opts)
    out = Path(args.out)
    if out.parent and not out.parent.exists():
        raise ParameterError(f"the directory of '{out}' does not exist")
    try:
        with stop_on_signals():  # Ctrl-C / SIGTERM: stop after the current replica
            cal = calibrate(params, options, progress=not args.quiet,
                            on_row=lambda partial: save_eos(partial, out))
    except KeyboardInterrupt:
        print(f"pedmesh: interrupted; the densities measured so far are in {out} "
              "(marked incomplete)", file=sys.stderr)
        return 130
    save_eos(cal, out)
    if not args.quiet:
        print("  rho [ped/m^2]   p [ped/s^2]     +- s.e.    mean field g1 rho^2/2   ratio")
        for r in cal["table"]:
            print(f"  {r['rho']:12.2f} {r['p']:13.4e} {r['p_err']:10.1e} {r['mean_field']:18.4e}"
                  f" {r['p'] / r['mean_field']:11.2e}")
    print(f"calibration of {len(cal['table'])} densities in {cal['seconds']:.0f} s "
          f"written to {out}")
    return 0
