"""``pedmesh report``: one self-contained HTML page of runs, comparisons and ensembles."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "write a self-contained HTML report of runs, a comparison or an ensemble"
DESCRIPTION = """\
Write one HTML page that a person reads in any browser, offline (every plot and the
little script of its time slider are inside the file; it loads nothing): a plain-language
summary, the room plan with exits, obstacles and start areas, the evacuation curve with
T50/T90/T100 as summary.json has them, the exit usage, the peak-density and level-of-
service maps, the crowd-safety measures (where the run recorded them), density snapshots
with a time slider, and the run's settings, parameters, provenance and warnings.

Each FOLDER is a run folder (pedmesh run), a compare folder (pedmesh compare: the models
side by side) or an ensemble folder (pedmesh ensemble: the 5-95 % bands and percentiles,
and a typical member). Several folders are shown side by side.

examples:
  pedmesh report runs/example2-sfm -o example2.html
  pedmesh report runs/example2-compare -o compare.html
  pedmesh report runs/ex2-sfm runs/ex2-eos -o side-by-side.html
  pedmesh report ensemble -o ensemble.html --frames 12
"""


def add_args(p: argparse.ArgumentParser) -> None:
    from ..report import DEFAULT_FRAMES, MAX_FRAMES

    p.add_argument("folders", nargs="+", metavar="FOLDER",
                   help="run, compare or ensemble folder(s)")
    p.add_argument("-o", "--output", metavar="FILE", default=None,
                   help="the HTML file to write (default: report.html in the first folder)")
    p.add_argument("--frames", type=int, default=DEFAULT_FRAMES, metavar="N",
                   help=f"density snapshots on the time slider, at most {MAX_FRAMES} "
                        f"(default: {DEFAULT_FRAMES})")
    p.add_argument("--title", default=None, help="the page's title (default: the room and "
                                                  "the runs)")


def run(args: argparse.Namespace) -> int:
    import time

    from ..io.run_folder import REPORT_HTML
    from ..report import write_report

    t0 = time.perf_counter()
    out = Path(args.output) if args.output else Path(args.folders[0]) / REPORT_HTML
    path = write_report(args.folders, out, frames=args.frames, title=args.title)
    size = path.stat().st_size
    print(f"wrote {path} ({size / 1e6:.1f} MB) in {time.perf_counter() - t0:.1f} s")
    return 0
