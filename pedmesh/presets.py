"""Parameter presets: named sets of model parameters, each value with its unit and source.

A run takes its parameters from, in order of precedence: ``--param NAME=VALUE`` overrides,
then the preset (``--preset NAME``, ``preset=`` in the Python API, or the room file's
``"preset"``), then the model's own defaults. A preset sets only the parameters a model
has (the continuum models take the speed law and the relaxation time, the social force
model everything).

* ``paper``: Table 1 of the paper, exactly: the paper's examples, ``reproduce_paper.py`` and
  the comparisons with the paper use it. It is the model defaults, so it reproduces every
  result made before presets existed.
* ``weidmann``: the paper's social force model with the desired speed of Weidmann's
  fundamental diagram (free speed 1.34 m/s, jam density 5.4 /m^2). Literature values, not
  fitted to experiments. Its routes converge as ``validated``'s do (``route_kernel`` 2 m,
  ``route_resolution`` 0.1 m: a route mesh of its own), and who leaves through an exit
  still counts in the density of those behind while walking on (``exit_ghosts``).
* ``validated`` (the default): the social force model's desired speed a table
  (``speed_law=table``) in its kernel density without one's own share (``density_self=0``,
  free speed 1.34 m/s), fitted by ``python -m pedmesh.fitting.fit_validated`` to the Juelich
  corridor runs (fed with the experiment's inflow), bottleneck flows and the fundamental
  diagram, with ``tau`` and the repulsion strength ``A`` of its earlier fit of Weidmann's
  law, and the terms for crowds that press (a space requirement that shrinks with the
  desired speed, queueing or crowding: ``shrink``, ``t_space``, ``crowd_stretch``,
  ``crowd_knee``, ``queue_width``, ``crowd_width``) fitted by ``fit_validated --law crowd``
  to both entrances of the corridor runs, the published bottleneck flows and the densities
  in front of entrances (``pedmesh/data/validated.json``; ``docs/validation/fit.md``), Table 1
  otherwise. Since issue 44 its routes converge (``route_kernel``, ``route_clearance`` and
  ``route_resolution``: the social force model walks on a route mesh of its own) and its
  door physics reads the crowd ahead (``density_cone``) with a wall's social force scaled
  (``wall_repulsion``), and the table and dense-crowd terms were fitted anew with the
  doors in a thin wall among the targets (``fit_validated --law converged``); its exits
  read as doors with the world beyond them (``exit_ghosts``: who leaves still counts in
  the density of those behind while walking on; ``fit_validated --law exits``). The
  continuum models take the fitted SFM's own fundamental diagram, measured by
  ``python -m pedmesh.fitting.continuum_law`` (``pedmesh/data/fd_validated.json``), as
  their table (:attr:`Preset.continuum`); ``eos`` takes the equation of state measured with
  these parameters (``pedmesh/data/eos_validated.json``) and reads its law near exits at
  the density less the kernel's mass beyond the exit (``exit_kernel`` = R), where the
  social force model's people read the crowd thinning ahead of them.

``pedmesh presets`` lists them with values, units and sources.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from . import parameters as P
from .errors import ParameterError

__all__ = ["Preset", "PRESETS", "DEFAULT_PRESET", "fingerprint", "get_preset",
           "preset_overrides", "resolve_preset"]

TABLE1 = P.TABLE1_SOURCE
WEIDMANN = P.WEIDMANN_SOURCE


@dataclass(frozen=True)
class Value:
    """One preset value: the value, its SI unit and where it comes from."""

    value: float | str
    unit: str
    source: str


@dataclass(frozen=True)
class Preset:
    """A named parameter set (see the module docstring). ``continuum``: values the
    continuum models take instead of those of ``values`` (e.g. their own desired-speed
    law: the social force model's measured fundamental diagram)."""

    name: str
    description: str
    values: dict[str, Value] = field(default_factory=dict)
    continuum: dict[str, Value] = field(default_factory=dict)

    def overrides(self, accepted: set[str] | None = None, *,
                  continuum: bool = False) -> dict[str, float | str]:
        """The values as ``--param`` overrides, only those in ``accepted`` (if given);
        with ``continuum``, a continuum model's (:attr:`continuum` over :attr:`values`)."""
        values = {**self.values, **self.continuum} if continuum else self.values
        return {k: v.value for k, v in values.items() if accepted is None or k in accepted}


#: Table 1, as the model defaults declare it (pedmesh.parameters)
_PAPER_VALUES = {
    "speed_law": Value(P.get("speed_law").default, "",
                       TABLE1 + ": U_e = U_f exp(-beta rho)"),
    **{p.name: Value(p.default, p.unit, p.source) for p in P.TABLE1},
}


def _unit(name: str) -> str:
    return P.get(name).unit


DATA = Path(__file__).resolve().parent / "data"
FIT = ("fitted to the Juelich corridor runs and bottleneck flows "
       "(pedmesh.fitting.fit_validated -> pedmesh/data/validated.json)")


def _validated() -> "Preset | None":
    """The ``validated`` preset from the fit's record ``pedmesh/data/validated.json`` (None
    without it): Table 1 for what the fit left alone, Weidmann's law with the fitted values,
    and for ``eos`` the equation of state measured with these parameters
    (``pedmesh/data/eos_validated.json``)."""
    path = DATA / "validated.json"
    if not path.is_file():
        return None
    fit = json.loads(path.read_text())
    fitted = set(fit.get("fitted", []))
    values = {k: v for k, v in _PAPER_VALUES.items() if k != "beta"}
    for k, v in fit["parameters"].items():
        if k not in P.PARAMETERS:  # (not a parameter, e.g. the preset the fit started from)
            continue
        if k in fitted:
            src = FIT + ("; U_e/U_f at the kernel density without one's own share"
                         if k == "speed_table" else "")
        elif k == "speed_table" and k in fit.get("carried", {}):
            src = (FIT + " (--law table); U_e/U_f at the kernel density without one's own "
                   "share, kept when the dense-crowd terms were fitted")
        elif k in fit.get("carried", {}):
            src = ("fitted with Weidmann's law to the same data (pedmesh.fitting.fit_validated "
                   "--law weidmann), kept when the law was fitted as a table")
        elif k == "crowd_width":
            src = "Adrian et al. 2020: crowding from corridors 2.3 m wide on"
        elif k == "t_space":
            src = ("chosen by probes before the fit (pedmesh.fitting.fit_validated --law crowd; "
                   "docs/validation/dense_crowds.md)")
        elif k == "speed_law" and v == "table":
            src = "pedmesh: U_e = U_f g(rho), g piecewise linear through speed_table's points"
        elif k == "U_f":
            src = WEIDMANN + "; free walking speed 1.34 m/s"
        elif k == "density_self":
            src = "pedmesh: U_e without one's own kernel share, so a lone walker walks at U_f"
        elif k == "exit_ghosts":
            src = P.get(k).source + "; fixed in the fit (fit_validated --law exits)"
        elif k in ("route_kernel", "route_resolution", "route_clearance", "density_cone",
                   "wall_repulsion"):
            src = (P.get(k).source + "; fixed in the fit (issue 44: routes that converge, "
                   "door physics)")
        elif k in ("speed_law", "rho_jam", "gamma_w"):
            src = WEIDMANN
        else:
            src = values[k].source if k in values else FIT
        values[k] = Value(v, _unit(k), src)
    continuum: dict[str, Value] = {}
    fd = DATA / "fd_validated.json"
    if fit["parameters"].get("speed_law") == "table":
        # the social force model's law is a table in its kernel density; the continuum
        # models take its fundamental diagram, measured, as theirs
        if fd.is_file():
            continuum["speed_table"] = Value(
                json.loads(fd.read_text())["speed_table"], _unit("speed_table"),
                "the validated SFM's fundamental diagram (speed/U_f at the crowd's density), "
                "measured by pedmesh.fitting.continuum_law -> pedmesh/data/fd_validated.json")
    # the continuum models: the same law, shifted by the kernel share the social force model
    # leaves out, so that both have one fundamental diagram
    elif not fit["parameters"].get("density_self", 1):
        R = float(fit["parameters"].get("R", _PAPER_VALUES["R"].value))
        values["rho_shift"] = Value(round(1.0 / (math.pi * R * R), 6), _unit("rho_shift"),
                                    "1/(pi R^2): the continuum models' law at rho - 1/(pi R^2),"
                                    " the validated SFM's fundamental diagram")
    # eos: near an exit its law is read at a density less the kernel's mass beyond the exit,
    # where the social force model's people read a crowd thinning ahead of them
    continuum["exit_kernel"] = Value(
        float(fit["parameters"].get("R", _PAPER_VALUES["R"].value)), _unit("exit_kernel"),
        "the validated SFM's kernel width R: eos reads its law near exits at the density "
        "less that kernel's mass beyond the exit, where the SFM's people read the crowd "
        "thinning ahead (docs/validation/dense_crowds.md, exit_ghosts.md)")
    cone = float(fit["parameters"].get("density_cone", 0.0) or 0.0)
    if cone > 0:  # eos: the SFM's people at an exit look through it
        continuum["exit_cone"] = Value(
            cone, _unit("exit_cone"),
            "the validated SFM's density_cone: eos weighs the kernel mass beyond an exit as "
            "the social force model's people heading out see it")
    eos = DATA / "eos_validated.json"
    if eos.is_file():
        values["calibration"] = Value(str(eos), _unit("calibration"),
                                      "pedmesh calibrate --preset validated "
                                      "(the eos model's equation of state)")
    return Preset("validated", "fitted to real crowds (Juelich corridor experiments, "
                               "bottleneck flows, free walking speed); see "
                               "docs/validation/", values, continuum)


#: the social force model's routes on their own mesh (issue 44), in the presets that are not
#: the paper's: the route reads the crowd on a 2 m scale and is solved on a route mesh
#: resolved at 0.1 m at the exits and corners, so that the run's mesh does not change the
#: answer (docs/validation/route_convergence.md)
_ROUTES = {k: Value(v, _unit(k), P.get(k).source + "; issue 44: routes that converge")
           for k, v in (("route_kernel", 2.0), ("route_resolution", 0.1))}

#: people who leave still count in the density of those behind them while they walk on
#: beyond the exit (issue 44), in the presets that are not the paper's
_EXITS = {"exit_ghosts": Value(1, _unit("exit_ghosts"), P.get("exit_ghosts").source)}

PRESETS: dict[str, Preset] = {
    "paper": Preset(
        "paper", "the paper's Table 1, exactly (the model defaults; the paper's examples "
                 "name it)", dict(_PAPER_VALUES)),
    "weidmann": Preset(
        "weidmann", "Table 1 with the desired speed of Weidmann's fundamental diagram "
                    "(literature values, not fitted)",
        {**{k: v for k, v in _PAPER_VALUES.items() if k != "beta"},
         "speed_law": Value("weidmann", "",
                            WEIDMANN + ": U_e = U_f (1 - exp(-gamma_w (1/rho - 1/rho_jam)))"),
         "U_f": Value(1.34, _unit("U_f"), WEIDMANN),
         **{k: Value(P.get(k).default, _unit(k), WEIDMANN) for k in ("rho_jam", "gamma_w")},
         **_ROUTES, **_EXITS}),
}

if (_v := _validated()) is not None:
    PRESETS["validated"] = _v

#: the preset of a run that names none (neither the command nor the room file)
DEFAULT_PRESET = "validated"


def get_preset(name: str) -> Preset:
    """The preset called ``name``; a one-line error naming the known ones otherwise."""
    if not isinstance(name, str) or name not in PRESETS:
        raise ParameterError(f"unknown preset {name!r} (presets: {', '.join(PRESETS)})")
    return PRESETS[name]


def fingerprint(name: str) -> str:
    """A short hash (16 hex digits) of what preset ``name`` sets: its values, its continuum
    models' values, and the contents of the files a value names (the eos calibration).
    Results computed under a preset are stale once its fingerprint changes (a refit): the
    resumable studies (benchmarks/convergence.py) store it with each run and run again
    what was computed under another."""
    import hashlib

    preset = get_preset(name)
    h = hashlib.sha256()
    for part in (preset.values, preset.continuum):
        for k in sorted(part):
            v = part[k].value
            if isinstance(v, str) and v.endswith(".json") and Path(v).is_file():
                # (the file's name and bytes, not where this checkout keeps it)
                h.update(json.dumps([k, Path(v).name]).encode() + Path(v).read_bytes())
            else:
                h.update(json.dumps([k, v], sort_keys=True, default=str).encode())
        h.update(b"|")
    return h.hexdigest()[:16]


def resolve_preset(explicit: str | None, room: Any = None) -> str:
    """The preset a run uses: the one asked for, else the room file's, else the default."""
    name = explicit if explicit is not None else getattr(room, "preset", None)
    name = DEFAULT_PRESET if name is None else name
    get_preset(name)
    return name


def preset_overrides(name: str, accepted: set[str] | frozenset[str],
                     overrides: dict[str, Any] | None = None, *,
                     continuum: bool = False) -> dict[str, Any]:
    """The parameters of a model with the parameters ``accepted`` (e.g.
    :attr:`pedmesh.models.ModelEntry.parameter_names`) under preset ``name``: the preset's
    values for those, then ``overrides`` on top. ``continuum``: a continuum model's, which
    takes the preset's continuum values (:attr:`Preset.continuum`)."""
    out = get_preset(name).overrides(set(accepted), continuum=continuum)
    out.update(overrides or {})
    return out
