"""Write the command-line reference from the ``pedmesh`` parsers themselves.

    python docs/render_cli.py            # writes docs/_generated/cli.md

``docs/conf.py`` runs it at every build, so the page is always what ``pedmesh --help`` and
``pedmesh COMMAND --help`` print: the help of each command as a literal block, wrapped at
100 columns. The help texts are written for a terminal (aligned tables, indented
examples), so they are shown as they are, not read as reStructuredText.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
OUT = DOCS / "_generated" / "cli.md"
WIDTH = 100


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def render() -> str:
    """The Markdown of the reference: ``pedmesh --help``, then a section per command."""
    from pedmesh.cli._main import build_parser

    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(WIDTH + 2)  # argparse wraps at COLUMNS - 2
    try:
        parser = build_parser()
        parts = ["```text", parser.format_help().rstrip(), "```", ""]
        for name, sub in _subparsers(parser).items():
            parts += [f"## pedmesh {name}", "", "```text", sub.format_help().rstrip(), "```",
                      ""]
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old
    return "\n".join(parts)


def main(out: Path = OUT) -> Path:
    """Write the reference to ``out`` (only if it changed, so Sphinx rebuilds it only then)."""
    text = render()
    out.parent.mkdir(parents=True, exist_ok=True)
    if not out.exists() or out.read_text(encoding="utf-8") != text:
        out.write_text(text, encoding="utf-8")
    return out


if __name__ == "__main__":
    sys.path.insert(0, str(DOCS.parent))
    print(f"wrote {main()}")
