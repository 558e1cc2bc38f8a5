"""The ``pedmesh`` command line: ``main(argv)`` plus one module per subcommand."""

from ._main import main

__all__ = ["main"]
