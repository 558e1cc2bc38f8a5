"""Entry point of the ``pedmesh`` command: parser, subcommand dispatch, error reporting.

Every :class:`~pedmesh.errors.PedmeshError` becomes one line on stderr and exit status 2;
``--debug`` (anywhere on the command line) shows the traceback instead.

Start-up (issue 46): a command line parses with the parser of its own command only (that
command's module imported, no other), and parsing imports neither the models nor the run
driver (nor numba through them): help texts that name something from them (the models, the
output files, the size limits) are callables, filled in when the help is shown
(:class:`_Parser`). The command imports what it needs when it runs.
"""

from __future__ import annotations

import argparse
import gc
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


class _Parser(argparse.ArgumentParser):
    """An argument parser whose description and argument help texts may be callables
    returning the text, called when the help is first formatted: the texts that name what
    only a slow import knows (the registered models, the run's output files and limits),
    so that building a parser and parsing a command line import none of it."""

    def format_help(self) -> str:
        if callable(self.description):
            self.description = self.description()
        for action in self._actions:
            if callable(action.help):
                action.help = action.help()
        return super().format_help()


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``pedmesh`` parser with every subcommand, or with ``command`` only (what
    :func:`main` parses a command line with: only that command's module is imported)."""
    parser = _Parser(
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
        if command is not None and name != command:
            continue
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
    """Run the ``pedmesh`` command; returns the exit status. Without ``argv`` (the
    ``pedmesh`` program itself: the command line from ``sys.argv``) the objects alive at the
    end are frozen out of the garbage collector (:func:`_before_exit`)."""
    program = argv is None
    if program:
        _full_collections_rarely()
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    argv = [a for a in argv if a != "--debug"]
    try:
        return _main(argv, debug)
    finally:
        if program:
            _before_exit()


#: the program's garbage collector runs a full collection at most once every this many
#: collections of the middle generation (Python's default: 10)
FULL_COLLECTION_EVERY = 100


def _full_collections_rarely() -> None:
    """The ``pedmesh`` program collects its oldest generation a tenth as often as Python
    does by default. Starting a run leaves about 175,000 objects that live as long as the
    process (modules, numba's types and compiled kernels), and every full collection
    traverses all of them: three of them took 0.1-0.15 s of a 1.7 s ``pedmesh run``
    (issue 46). The young generations are collected as usual, so short-lived cycles (all
    a run makes while it steps) are freed as soon as before."""
    g0, g1, g2 = gc.get_threshold()
    gc.set_threshold(g0, g1, max(g2, FULL_COLLECTION_EVERY))


def _before_exit() -> None:
    """The process is about to end: move every object alive now to the garbage
    collector's permanent generation, so that the collections the interpreter makes as it
    shuts down do not traverse them again (a run ends with about 175,000 of them, most
    numba's types and compiled kernels): those collections took 0.3-0.4 s of a 2 s
    ``pedmesh run`` (issue 46). The objects are still released as the interpreter clears
    its modules; only reference cycles among them stay unreclaimed, at exit, where the
    system frees the memory anyway (open files are closed by the commands themselves)."""
    gc.freeze()


def _main(argv: list[str], debug: bool) -> int:
    parser = build_parser(argv[0] if argv and argv[0] in SUBCOMMANDS else None)
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
