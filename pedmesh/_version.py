"""The package version (one place; the package, the CLI and run summaries read it)."""

__version__ = "0.1.0"
