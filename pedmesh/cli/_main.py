"""Entry point of the ``pedmesh`` command: parser, subcommand dispatch, error reporting.

Every :class:`~pedmesh.errors.PedmeshError` becomes one line on stderr and exit status 2;
``--debug`` (anywhere on the command line) shows the traceback instead.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from .._version import __version__
from ..errors import PedmeshError

# subcommand name -> module (each provides add_args(parser) and run(args) -> int)
SUBCOMMANDS = {
    "mesh": "pedmesh.cli.cmd_mesh",
    "route": "pedmesh.cli.cmd_route",
    "run": "pedmesh.cli.cmd_run",
    "compare": "pedmesh.cli.cmd_compare",
    "calibrate": "pedmesh.cli.cmd_calibrate",
    "ensemble": "pedmesh.cli.cmd_ensemble",
    "export": "pedmesh.cli.cmd_export",
    "presets": "pedmesh.cli.cmd_presets",
    "animate": "pedmesh.cli.cmd_animate",
    "report": "pedmesh.cli.cmd_report",
}


class _Version(argparse.Action):
    """``--version``: the version and the threading layer of the parallel kernels (found
    only when asked: it starts numba)."""

    def __call__(self, parser, namespace, values, option_string=None):
        from ..models.continuum.solver import threading_note

        print(f"pedmesh {__version__}\n{threading_note()}")
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pedmesh",
        description=(
            "Pedestrian crowd simulation on triangulated rooms: social force model and "
            "continuum models on one mesh, routed by fast marching. Units: m, s, ped/m^2."
        ),
        epilog="Add --debug anywhere to see a full traceback on errors.",
    )
    parser.add_argument("--version", action=_Version, nargs=0,
                        help="show the version and the threading layer, and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, modname in SUBCOMMANDS.items():
        mod = importlib.import_module(modname)
        p = sub.add_parser(
            name,
            help=mod.HELP,
            description=mod.DESCRIPTION,
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        mod.add_args(p)
        p.set_defaults(func=mod.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the ``pedmesh`` command; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    argv = [a for a in argv if a != "--debug"]
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt as exc:  # (before PedmeshError: a RunInterrupted is both)
        if debug:
            raise
        print(f"pedmesh: {exc}" if str(exc) else "pedmesh: interrupted", file=sys.stderr)
        return 130
    except PedmeshError as exc:
        if debug:
            raise
        print(f"pedmesh: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        if debug:
            raise
        where = f" {exc.filename}" if getattr(exc, "filename", None) else ""
        print(f"pedmesh: error:{where} {exc.strerror or exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # a bug: still one line, with a way to see more
        if debug:
            raise
        print(f"pedmesh: internal error: {type(exc).__name__}: {exc} "
              "(rerun with --debug for the traceback; please report it)", file=sys.stderr)
        return 1
