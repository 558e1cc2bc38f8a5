"""``pedmesh presets``: the parameter presets with their values, units and sources."""

from __future__ import annotations

import argparse

HELP = "list the parameter presets (values, units, sources)"
DESCRIPTION = """\
List the parameter presets that --preset NAME selects on `pedmesh run`, `compare` and
`calibrate` (a room file may name its own with "preset": NAME). Precedence: --param
overrides, then the preset, then the model's defaults; a preset sets only the parameters a
model has. A run that names no preset uses the default (marked below).

examples:
  pedmesh presets
  pedmesh presets paper
"""


def add_preset_arg(p: argparse.ArgumentParser) -> None:
    """The --preset option of the commands that run models."""
    from ..presets import DEFAULT_PRESET, PRESETS

    p.add_argument("--preset", default=None, metavar="NAME",
                   help=f"parameter preset ({', '.join(PRESETS)}; default: the room file's, "
                        f"else {DEFAULT_PRESET}); see `pedmesh presets`")


def add_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("name", nargs="?", default=None, help="show only this preset")


def run(args: argparse.Namespace) -> int:
    from ..presets import DEFAULT_PRESET, PRESETS, get_preset

    names = [get_preset(args.name).name] if args.name else list(PRESETS)
    for n, name in enumerate(names):
        pre = PRESETS[name]
        mark = " (default)" if name == DEFAULT_PRESET else ""
        if n:
            print()
        print(f"{name}{mark}: {pre.description}")
        width = max(len(k) for k in pre.values)
        for key, v in pre.values.items():
            value = v.value if isinstance(v.value, str) else f"{v.value:g}"
            print(f"  {key:<{width}}  {value:>11} {v.unit:<9} {v.source}")
    return 0
