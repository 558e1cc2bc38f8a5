"""``pedmesh presets``: the parameter presets with their values, units and sources."""

from __future__ import annotations

import argparse
import textwrap

HELP = "list the parameter presets (values, units, sources)"
DESCRIPTION = """\
List the parameter presets that --preset NAME selects on `pedmesh run`, `compare` and
`calibrate` (a room file may name its own with "preset": NAME). Precedence: --param
overrides, then the preset, then the model's defaults; a preset sets only the parameters a
model has. A run that names no preset uses the default (marked below).

With --model NAME it lists instead every parameter that model takes (what --param NAME=VALUE
may set): its default, unit, allowed values and meaning, as declared in pedmesh.

examples:
  pedmesh presets
  pedmesh presets paper
  pedmesh presets --model eos
"""


def add_preset_arg(p: argparse.ArgumentParser) -> None:
    """The --preset option of the commands that run models."""
    from ..presets import DEFAULT_PRESET, PRESETS

    p.add_argument("--preset", default=None, metavar="NAME",
                   help=f"parameter preset ({', '.join(PRESETS)}; default: the room file's, "
                        f"else {DEFAULT_PRESET}); see `pedmesh presets`")


def add_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("name", nargs="?", default=None, help="show only this preset")
    p.add_argument("--model", default=None, metavar="MODEL",
                   help="list the parameters of this model instead (defaults, units, "
                        "allowed values, meaning)")


def _parameters(model: str) -> int:
    """The declared parameters of ``model`` (pedmesh.parameters) as a table."""
    from ..models import get_model

    entry = get_model(model)
    print(f"{entry.name} ({entry.scale}): {entry.description}")
    width = max(len(p.name) for p in entry.parameters)
    for p in entry.parameters:
        default = "None" if p.default is None else (
            p.default if isinstance(p.default, str) else f"{p.default:g}")
        default = default if default != "" else "''"
        print(f"  {p.name:<{width}}  {default:>11} {p.unit:<9} {p.bounds}")
        for line in textwrap.wrap(p.description, 78 - width):
            print(f"  {'':<{width}}    {line}")
    return 0


def _show(key: str, v, width: int) -> None:
    """One value's lines: name, value, unit, source (a long text value on lines of its
    own, e.g. a speed table)."""
    value = v.value if isinstance(v.value, str) else f"{v.value:g}"
    if len(value) > 11:
        print(f"  {key:<{width}}  {'':>11} {v.unit:<9} {v.source}")
        for line in textwrap.wrap(value, 72):
            print(f"  {'':<{width}}    {line}")
        return
    print(f"  {key:<{width}}  {value:>11} {v.unit:<9} {v.source}")


def run(args: argparse.Namespace) -> int:
    from ..presets import DEFAULT_PRESET, PRESETS, get_preset

    if args.model is not None:
        return _parameters(args.model)
    names = [get_preset(args.name).name] if args.name else list(PRESETS)
    for n, name in enumerate(names):
        pre = PRESETS[name]
        mark = " (default)" if name == DEFAULT_PRESET else ""
        if n:
            print()
        print(f"{name}{mark}: {pre.description}")
        width = max(len(k) for k in [*pre.values, *pre.continuum])
        for key, v in pre.values.items():
            _show(key, v, width)
        if pre.continuum:
            print("  continuum models (eos, rdue, pw, mac1, mac2-*) instead:")
            for key, v in pre.continuum.items():
                _show(key, v, width)
    return 0
