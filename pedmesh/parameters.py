"""Every model parameter, declared once: name, SI unit, default, bounds, meaning and source.

A :class:`Parameter` is the one home of a parameter. The social force model's and the
continuum's parameter classes take their fields from it (:func:`field`), the run checks
values with it (:meth:`Parameter.check`), the command line parses ``--param NAME=VALUE``
with it (:func:`parse_overrides`), the presets take units and the paper's values from it,
``pedmesh presets`` and the documentation's parameter tables print it, and summary.json
lists the values it checked.

The built-in parameters are declared below, in :data:`PARAMETERS`, grouped by meaning;
the paper's Table 1 (:data:`TABLE1`) is written here and nowhere else. A model added from
outside declares its own with :class:`Parameter` and names them in its registry entry
(:class:`pedmesh.models.ModelEntry`); :func:`declare` makes them known to the parser.

Two kinds of limits. A parameter's *bounds* (``low``/``high``) are what its mathematics
needs (a relaxation time must be positive); its *range* (``range``) is the physical range a
run accepts (a relaxation time from 1 ms to 1000 s), and lies within the bounds. Every run
checks the range, wherever its values come from (``--param``, a preset, a room file's
preset, :func:`pedmesh.simulate`, a model built through the registry): :func:`check_values`,
:func:`check_fields` (the records a run is made of: the social force model's
``SocialForceParams`` and ``SFMNumerics``, the continuum's ``FVOptions`` and
``MacroRunOptions``) and :meth:`Parameter.check` check it by default, and a value outside is
one line naming the range (``parameter 'U_f' must be in [0.1, 10] m/s, got 1e+300``). The
continuum models' physics classes (the finite-volume core's objects, made by
:func:`pedmesh.models.continuum.adapter.macro_model`) check only the bounds
(``physical=False``), so that numerical tests may switch a term off with a value no person
has (``tau=1e30``: no relaxation); the run around them has checked the range first.

This module sits at the bottom of the package: it imports nothing of pedmesh but the
errors.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Callable, Iterable, Mapping

import numpy as np

from .errors import ParameterError

__all__ = ["Parameter", "PARAMETERS", "TABLE1", "ROUTES", "TABLE1_SOURCE", "DEFAULT_T_END_S",
           "DEFAULTS", "declare", "get", "field", "check_fields", "check_values",
           "parse_overrides", "defaults"]

#: where the paper's values come from
TABLE1_SOURCE = "paper, Table 1"
WEIDMANN_SOURCE = ("Weidmann (1993), Transporttechnik der Fussgaenger, ETH Zurich "
                   "(RiMEA 4.1.1)")
ADRIAN_SOURCE = "Adrian, Seyfried & Sieben, J. R. Soc. Interface 2020"

#: [s] a run stops at this simulated time if people remain (``--t-end``)
DEFAULT_T_END_S = 1000.0

#: the kinds of value a parameter takes
KINDS = ("real", "integer", "switch", "text")


@dataclass(frozen=True)
class Parameter:
    """One model parameter.

    ``kind``: ``real`` (a finite number within the bounds), ``integer`` (a whole number
    within the bounds, or one of ``choices``), ``switch`` (0 or 1, off or on) or ``text``
    (a word or a path). ``low``/``high``: bounds [unit] (None: unbounded), open unless
    ``low_closed``/``high_closed``: what the mathematics needs. ``range``: the physical
    range ``(lo, hi)`` [unit], closed, within the bounds: what a run accepts (see the module
    docstring; None: the bounds only). ``optional``: None is allowed (the model derives the
    value from the others). ``cast``: applied to a checked value (e.g. ``int``, ``bool``),
    None: the value is kept as given.
    """

    name: str
    default: Any
    unit: str = "-"
    description: str = ""
    source: str = "pedmesh"
    kind: str = "real"
    low: float | None = None
    high: float | None = None
    low_closed: bool = False
    high_closed: bool = False
    choices: tuple = ()
    optional: bool = False
    cast: Callable[[Any], Any] | None = None
    range: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"parameter kind must be one of {KINDS}, got {self.kind!r}")
        if self.range is not None:
            lo, hi = self.range
            if not (self.kind in ("real", "integer") and not self.choices
                    and math.isfinite(lo) and math.isfinite(hi) and lo < hi
                    and not self._outside_bounds(lo) and not self._outside_bounds(hi)):
                raise ValueError(f"parameter '{self.name}': range {self.range!r} must be "
                                 f"finite, increasing and within its bounds")

    # ------------------------------------------------------------------ checks
    @property
    def bounds(self) -> str:
        """The allowed values of a run in words (for messages and tables): the physical
        range where there is one, else the bounds (:attr:`limits`)."""
        if self.range is not None:
            return f"in [{self.range[0]:g}, {self.range[1]:g}]"
        return self.limits

    @property
    def limits(self) -> str:
        """The bounds (what the mathematics needs) in words."""
        if self.kind == "switch":
            return "0 or 1"
        if self.choices:
            c = [str(x) for x in self.choices]
            return ", ".join(c[:-1]) + " or " + c[-1]
        if self.kind == "text":
            return "text"
        lo, hi = self.low, self.high
        if lo == 0 and not self.low_closed and hi is None:
            return "positive"
        if hi is None and lo is not None:
            return f">= {lo:g}" if self.low_closed else f"> {lo:g}"
        if lo is None and hi is not None:
            return f"<= {hi:g}" if self.high_closed else f"< {hi:g}"
        if lo is None and hi is None:
            return "any" + (" whole number" if self.kind == "integer" else " finite number")
        return (f"in {'[' if self.low_closed else '('}{lo:g}, {hi:g}"
                f"{']' if self.high_closed else ')'}")

    def _outside_bounds(self, value: float) -> bool:
        lo_bad = self.low is not None and (value < self.low if self.low_closed
                                           else not value > self.low)
        hi_bad = self.high is not None and (value > self.high if self.high_closed
                                            else not value < self.high)
        return lo_bad or hi_bad

    def _unit_text(self) -> str:
        return "" if self.unit in ("", "-") else f" {self.unit}"

    def check(self, value: Any, *, physical: bool = True) -> Any:
        """``value`` checked (and cast); a one-line :class:`~pedmesh.errors.ParameterError`
        naming the parameter otherwise. ``physical``: within the physical range
        (:attr:`range`), as every run needs; False: within the bounds only (the continuum
        physics classes, see the module docstring)."""
        name = self.name
        if value is None and self.optional:
            return None
        if self.kind == "text":
            if not isinstance(value, str):
                raise ParameterError(f"parameter '{name}' must be text, got {value!r}")
            return value
        if self.kind == "switch":
            if isinstance(value, str) or not _is_number(value, allow_bool=True) \
                    or value not in (0, 1):
                raise ParameterError(f"parameter '{name}' must be 0 or 1 (off or on), "
                                     f"got {value!r}")
            return self.cast(value) if self.cast else value
        if not _is_number(value):
            raise ParameterError(f"parameter '{name}' must be a number, got {value!r}")
        if not math.isfinite(value):
            raise ParameterError(f"parameter '{name}' must be a finite number, got {value!r}")
        if self.choices:
            if value not in self.choices:
                raise ParameterError(f"parameter '{name}' must be {self.bounds}, got {value!r}")
        else:
            what = self.bounds if physical else self.limits
            if self.kind == "integer" and value != int(value):
                raise ParameterError(f"parameter '{name}' must be a whole number "
                                     f"{what}, got {value!r}")
            outside = self._outside_bounds(value)
            if physical and self.range is not None:
                outside = outside or not self.range[0] <= value <= self.range[1]
            if outside:
                if self.kind == "integer":
                    what = "a whole number " + what
                unit = self._unit_text() if (physical and self.range is not None) else ""
                raise ParameterError(f"parameter '{name}' must be {what}{unit}, "
                                     f"got {value!r}")
        return self.cast(value) if self.cast else value

    def parse(self, text: str) -> Any:
        """The value of ``--param NAME=TEXT``: words for text parameters, 0/1/false/true for
        switches (read as 0.0/1.0), numbers otherwise (checked for finiteness here, against
        the bounds by :meth:`check` when the model is built)."""
        return _parse(self.name, text, self.kind)

    def row(self) -> dict[str, Any]:
        """The declaration as a table row (``pedmesh presets``, the documentation)."""
        return {"name": self.name, "default": self.default, "unit": self.unit,
                "bounds": self.bounds, "range": self.range, "description": self.description,
                "source": self.source}


def _is_number(v: Any, allow_bool: bool = False) -> bool:
    if isinstance(v, (bool, np.bool_)):
        return allow_bool
    return isinstance(v, (int, float, np.integer, np.floating))


_BOOL_WORDS = {"0": 0.0, "1": 1.0, "false": 0.0, "true": 1.0}


def _parse(name: str, text: str, kind: str) -> Any:
    if kind == "text":
        return text.strip()
    if kind == "switch":
        word = text.strip().lower()
        try:  # 0, 1, 0.0, 1e0 ... as numbers
            word = {0.0: "0", 1.0: "1"}.get(float(word), word)
        except ValueError:
            pass
        if word not in _BOOL_WORDS:
            raise ParameterError(f"parameter '{name}' must be 0 or 1 (or false/true), "
                                 f"got '{text.strip()}'")
        return _BOOL_WORDS[word]
    try:
        value = float(text)
    except ValueError:
        raise ParameterError(f"parameter '{name}': '{text}' is not a number") from None
    if not math.isfinite(value):
        raise ParameterError(f"parameter '{name}' must be a finite number, got {text.strip()}")
    return value


# ---------------------------------------------------------------------- the catalogue
#: every declared parameter by name (the built-ins below, and those of models registered
#: from outside, see :func:`declare`)
PARAMETERS: dict[str, Parameter] = {}


def declare(*params: Parameter) -> tuple[Parameter, ...]:
    """Make parameters known by name (to the parser and the docs). A name may be declared
    once; declaring the same declaration again is harmless."""
    for p in params:
        old = PARAMETERS.get(p.name)
        if old is not None and old != p:
            raise ValueError(f"parameter '{p.name}' is already declared differently")
        PARAMETERS[p.name] = p
    return params


def get(name: str) -> Parameter:
    """The declaration of ``name``; a one-line error for unknown names."""
    try:
        return PARAMETERS[name]
    except KeyError:
        raise ParameterError(f"unknown parameter '{name}'") from None


def _positive(name, default, unit, description, source="pedmesh", **kw) -> Parameter:
    return Parameter(name, default, unit, description, source, low=0.0, **kw)


def _non_negative(name, default, unit, description, source="pedmesh", **kw) -> Parameter:
    return Parameter(name, default, unit, description, source, low=0.0, low_closed=True, **kw)


def _switch(name, default, description, source="pedmesh", cast=None) -> Parameter:
    return Parameter(name, default, "0/1", description, source, kind="switch", cast=cast)


#: the physical ranges (``Parameter.range``) are wide: each holds the values measured or
#: used in the literature (and by pedmesh's fits, benchmarks and tests of runs) with a wide
#: margin, and refuses what no crowd has (a desired speed of 1e300 m/s, a relaxation time
#: of 1e-300 s); where a range is not obvious, the description says why. Within a range a
#: run may still need a smaller time step (a runner's U_f = 5 m/s needs dt = 0.0025 s in
#: the social force model; its blow-up message says so).

#: the paper's Table 1: the social force model's physics, and the continuum models' where
#: they take the same quantity
TABLE1: tuple[Parameter, ...] = declare(
    _positive("U_f", 1.034, "m/s", "free-flow (desired) speed U_f (range: a shuffle to a "
              "run; Weidmann's free speeds are 1.34 +- 0.26 m/s, RiMEA's at most 2.22 m/s)",
              TABLE1_SOURCE, range=(0.1, 5.0)),
    _positive("beta", 0.05, "m^2/ped", "speed-density parameter of the exponential law "
              "U_e = U_f exp(-beta rho) (range: from a law that barely falls, U_e = 0.995 "
              "U_f at 5 /m^2, to one that halves by 0.07 /m^2)", TABLE1_SOURCE,
              range=(1e-3, 10.0)),
    _positive("tau", 0.5, "s", "relaxation time tau of the driving force (and of the "
              "continuum models' momentum relaxation; range: the literature's 0.1-1 s with "
              "a margin; the social force model's dt = 0.01 s resolves 0.05 s)",
              TABLE1_SOURCE, range=(0.05, 100.0)),
    _positive("m", 60.0, "kg", "pedestrian mass m (range: a small child to a heavy person "
              "with equipment)", TABLE1_SOURCE, range=(10.0, 500.0)),
    _positive("r", 0.15, "m", "body radius r_i (so r_ij = 2 r = 0.3 m; range: a child to a "
              "wheelchair with margin)", TABLE1_SOURCE, range=(0.05, 1.0)),
    _positive("R", 0.7, "m", "width of the Gaussian density kernel R (eq4)", TABLE1_SOURCE,
              range=(0.2, 10.0)),
    _positive("A", 2000.0, "N", "strength of the social repulsion A (range: 1 N, next to "
              "none, to 50 times the 2000 N of Helbing et al. 2000)", TABLE1_SOURCE,
              range=(1.0, 1e5)),
    _positive("B", 0.08, "m", "range of the social repulsion B", TABLE1_SOURCE,
              range=(0.01, 2.0)),
    _positive("k", 1.2e5, "kg/s^2", "body (contact) force constant k (range: about 1 % to "
              "80 times Table 1's)", TABLE1_SOURCE, range=(1e3, 1e7)),
    _positive("kappa", 2.4e5, "kg/(m s)", "sliding friction constant kappa (range: about "
              "0.4 % to 400 times Table 1's; benchmarks/corridor_flows.py probes 100 times)",
              TABLE1_SOURCE, range=(1e3, 1e8)),
)

#: the desired-speed law U_e(rho) (:mod:`pedmesh.speed`) besides U_f and beta
SPEED_LAW: tuple[Parameter, ...] = declare(
    Parameter("speed_law", "exponential", "",
              "the desired-speed law: 'exponential' (the paper's, U_f exp(-beta rho)), "
              "'weidmann' (U_f (1 - exp(-gamma_w (1/rho - 1/rho_jam)))) or 'table' (U_f "
              "g(rho), g piecewise linear through the points of speed_table)",
              TABLE1_SOURCE, kind="text"),
    _positive("rho_jam", 5.4, "ped/m^2", "jam density of the Weidmann law (range: up to "
              "the 10 /m^2 a start area may hold)", WEIDMANN_SOURCE, range=(1.0, 10.0)),
    _positive("gamma_w", 1.913, "ped/m^2", "how fast the Weidmann law's speed falls",
              WEIDMANN_SOURCE, range=(0.1, 10.0)),
    Parameter("speed_table", "", "ped/m^2 : -",
              "the points 'rho:g rho:g ...' (density : U_e/U_f) of the 'table' law",
              kind="text"),
    _non_negative("rho_shift", 0.0, "ped/m^2", "the law is read at rho - rho_shift (the "
                  "continuum models' copy of the social force model's own-share shift "
                  "1/(pi R^2))", range=(0.0, 10.0)),
)

#: the social force model's terms beyond Table 1 (off by default: the paper's model)
SFM_TERMS: tuple[Parameter, ...] = declare(
    _switch("density_self", 1.0, "1: U_e at the kernel density with the pedestrian's own "
            "share, as in the paper (eq3: a lone walker feels 1/(pi R^2) = 0.65 /m^2); 0: "
            "without it (a lone walker walks at U_f)", TABLE1_SOURCE + " (eq3)"),
    _non_negative("shrink", 0.0, "m", "speed-dependent space requirement: a person whose "
                  "desired speed is 0 keeps a social radius this much smaller than the body "
                  "radius r (0: off, the paper's model); body contact acts on the body radii",
                  range=(0.0, 1.0)),
    _positive("t_space", 1.06, "s", "the social radius grows by t_space/2 per m/s of the "
              "desired speed, back to r", "Seyfried et al. 2005: a walker needs 0.36 m + "
              "1.06 s x v", range=(0.01, 10.0)),
    Parameter("vision", 1.0, "-", "field of vision (Helbing's lambda): the social repulsion "
              "of someone straight behind counts this much, straight ahead fully (1: "
              "isotropic, the paper's model)", "Helbing & Molnar 1995; Helbing et al. 2000",
              low=0.0, high=1.0, low_closed=True, high_closed=True),
    Parameter("density_cone", 0.0, "-", "the desired speed reads the crowd ahead: in the "
              "kernel density each neighbour counts max(0, cos)^p times (p this value, cos "
              "the cosine between one's desired direction and the neighbour), normalised so "
              "that a uniform crowd reads its density; 0: every neighbour counts fully, the "
              "paper's eq3 (range: 0 to a cone narrower than a body's width at 1 m)",
              "a walker's speed follows the space in front (Seyfried et al., J. Stat. Mech. "
              "2005; the headway of Tordeux, Chraibi & Seyfried's collision-free speed "
              "model, 2016)", low=0.0, low_closed=True, range=(0.0, 16.0)),
    _switch("exit_ghosts", 0.0, "1: who leaves through an exit still counts in the kernel "
            "density of those behind, walking on beyond it (the law's speed at the density "
            "they read of the others beyond, never slower than they left, along their last "
            "desired direction, relaxing in tau) until twice the density cut-off "
            "from where they left: an exit is a line in a world that goes on; 0: gone at the "
            "line, and the front of a queue reads empty space ahead (the paper's model)",
            "pedmesh (issue 44): Example 2's 10 m exit as a door in a thin wall with room "
            "beyond passes 2.4 /(m s), removed at the line 2.8; published wide openings "
            "2.0-2.4 (docs/validation/exit_ghosts.md)"),
    Parameter("wall_repulsion", 1.0, "-", "the walls' social repulsion A exp((r - d)/B) "
              "as a share of the pedestrians' (1: Helbing's, the paper's; 0: a wall pushes "
              "only on contact, and the route keeps people off walls: route_clearance)",
              "Helbing, Farkas & Vicsek 2000 (walls as people); docs/validation/"
              "door_physics.md", low=0.0, high=1.0, low_closed=True, high_closed=True),
    Parameter("crowd_stretch", 1.0, "-", "queueing or crowding: where the free width is at "
              "least crowd_width, the speed law above crowd_knee is read at densities this "
              "many times lower (1: off, the paper's model)", ADRIAN_SOURCE, low=1.0,
              low_closed=True, range=(1.0, 10.0)),
    _positive("crowd_knee", 2.7, "ped/m^2", "the density above which crowding stretches the "
              "speed law", range=(0.1, 10.0)),
    _positive("queue_width", 1.2, "m", "free widths up to this queue (crowding factor 0)",
              ADRIAN_SOURCE, range=(0.1, 100.0)),
    _positive("crowd_width", 2.3, "m", "free widths from this on crowd (crowding factor 1)",
              ADRIAN_SOURCE, range=(0.1, 100.0)),
)

#: the route choice: what the route potential reads of the crowd
ROUTES: tuple[Parameter, ...] = declare(
    _positive("route_kernel", None, "m", "width L of the Gaussian kernel exp(-d^2/L^2) / "
              "(pi L^2) of the crowd density the route cost 1/U_e reads (None: the density "
              "kernel R at the route mesh's vertices, the paper's eq3; a length: the crowd's "
              "density on that scale, so that the route sees crowds, not the gaps between "
              "people, and is the same on any mesh that resolves L; range: from a body's "
              "reach to a hall)", "pedmesh (docs/validation/route_convergence.md): about "
              "the size of the areas in which crowd densities are measured (the Juelich "
              "corridors' 1.8 x 2 m)", optional=True, range=(0.5, 10.0)),
    _non_negative("route_clearance", 0.0, "m", "the route keeps off the walls: its cost "
                  "per metre rises towards a wall or obstacle within this distance, "
                  "(1 + 3 (1 - d/route_clearance)^2) times at d from it, four times on it, so "
                  "routes pass doors through their middle and keep a body's width off jambs "
                  "and walls (0: off, the paper's geodesics, which graze every corner)",
                  "a route is planned for the body's centre, which stays a radius and a "
                  "margin off walls (the boundary layers of the effective width, SFPE "
                  "Handbook: 0.15 m at walls to 0.46 m in wide concourses); "
                  "docs/validation/door_physics.md", range=(0.0, 5.0)),
)

#: the social force model's numerics
SFM_NUMERICS: tuple[Parameter, ...] = declare(
    _positive("dt", 0.01, "s", "time step of the SSP-RK3 integrator (range: a longer step "
              "does not resolve the body contact, whose period with Table 1's k and m is "
              "0.14 s)", range=(1e-4, 0.1)),
    _non_negative("route_interval", 1.0, "s", "interval between re-solves of the route "
                  "potential (0: every step; the direction is held in between)",
                  range=(0.0, 1000.0)),
    _positive("route_resolution", None, "m", "the social force model's routes, walls and "
              "crossings on a mesh of their own with edges of this length at the exits, "
              "an eighth of it at the reflex corners (door jambs, pillars; growing by 0.1 m "
              "per metre within 0.5 m of them), growing by 0.2 m per metre to a third of "
              "route_kernel (None: on the run's mesh, as the paper; the run's mesh then only "
              "carries the output)", optional=True, range=(0.01, 2.0)),
    _positive("route_refine", 1.0, "", "every edge of the social force model's route mesh "
              "divided by this (the edges at the exits and corners, along "
              "the walls and in the open): a check of the route's own discretisation "
              "(docs/validation/route_convergence.md); 1 in every preset",
              range=(1.0, 16.0)),
    _positive("force_cutoff", 1.2, "m", "interaction cut-off: A exp((0.3 - 1.2)/0.08) = "
              "0.026 N, 2e-4 of the driving force m U_f / tau = 124 N", range=(0.1, 10.0)),
    _positive("density_cutoff", 3.0, "R", "density-kernel cut-off in units of R: "
              "exp(-3^2) = 1.2e-4 of the kernel mass is cut", range=(1.0, 10.0)),
    Parameter("density_stages", 1, "-", "RK stages at which the kernel density (hence U_e) "
              "is evaluated: 1 = once per step, at its start; 3 = at every stage",
              kind="integer", choices=(1, 3), cast=int),
    _positive("max_speed", 10.0, "m/s", "a speed above this stops the run as a blow-up",
              range=(0.1, 100.0)),
    _non_negative("overlap_tolerance", 0.05, "m", "initial pedestrians may overlap their "
                  "bodies by at most this much", range=(0.0, 1.0)),
)

#: output and stopping settings every model has
RUN_OUTPUT: tuple[Parameter, ...] = declare(
    _positive("output_interval", 1.0, "s", "interval between density (and pedestrian) "
              "frames", range=(0.01, 1000.0)),
    _positive("sample_interval", 0.1, "s", "interval between rows of evacuation.csv and "
              "outflow.csv", range=(1e-3, 1000.0)),
)

#: the continuum models' physics beyond Table 1 and the speed law
CONTINUUM: tuple[Parameter, ...] = declare(
    _non_negative("c0", 1.0, "m/s", "Payne-Whitham's sound speed (momentum flux rho u u + "
                  "c0^2 rho; range: the speeds of people)", "Payne 1971; Whitham 1974",
                  range=(0.0, 10.0)),
    _positive("rho_cut", 1e-3, "ped/m^2", "below this density a film moves at its own "
              "velocity (first order), so it drains", range=(1e-6, 0.1)),
    _positive("u_max", None, "m/s", "largest speed (None: the model's default multiple of "
              "U_f, 2.5 U_f, 1.5 U_f for eos; range: up to 2.5 times the fastest U_f with "
              "margin)", optional=True, range=(0.1, 100.0)),
    _switch("walls", 1.0, "mac1: the walls repel, as the social force model's do"),
    _switch("friction", 1.0, "mac1: the sliding-friction term"),
    _positive("cutoff", 1.0, "m", "mac1: cut-off of the nonlocal kernels (must exceed the "
              "body diameter)", range=(0.1, 10.0)),
    _switch("split_friction", 1.0, "mac1: the stiff friction by Strang splitting around "
            "each step (0: inside the stages, cfl 0.4)"),
    _switch("imex", 1.0, "mac1: the local part of the repulsion as a pressure, implicit "
            "(0: the explicit scheme)"),
    _positive("lr_strength", 0.01, "-", "mac2: strength of the long-range repulsion",
              range=(1e-6, 10.0)),
    _positive("lr_length", 1.0, "m", "mac2: length of the long-range repulsion",
              range=(0.1, 100.0)),
    _positive("gamma1", None, "N m^4/(kg ped)", "mac2: the local pressure coefficient "
              "(None: from the Table 1 repulsion, 8.8; range: a sound speed sqrt(gamma1 "
              "rho) at 5 /m^2 from 0.07 to 70 m/s)", optional=True, range=(1e-3, 1e3)),
    Parameter("calibration", None, "", "eos: the equation-of-state file written by "
              "`pedmesh calibrate` (None: the one shipped for Table 1)", kind="text",
              optional=True),
    _non_negative("exit_kernel", 0.0, "m", "eos: near an exit the speed law is read at the "
                  "density the social force model's people see there, the crowd's less the "
                  "mass of their density kernel of this width beyond the exit (0: off, the "
                  "local density; the validated preset: the kernel width R)",
                  range=(0.0, 5.0)),
    _non_negative("exit_cone", 0.0, "-", "eos: the social force model's density cone at "
                  "exits (its density_cone): the kernel mass beyond an exit is weighted as "
                  "people heading out see it (0: the isotropic kernel; the validated preset: "
                  "its density_cone)", range=(0.0, 16.0)),
    _non_negative("lookahead", 0.0, "-", "eos: the speed law read at the density ahead, as "
                  "the social force model's people read theirs: the crowd's density averaged "
                  "with the kernel of width exit_kernel weighted by the density cone of this "
                  "exponent about the desired direction (nonlocal; needs exit_kernel > 0; 0: "
                  "off, the law at the local density, in every preset; the social force "
                  "model's density_cone, 2, is its counterpart)", "Colombo, Garavello & "
                  "Lecureux-Mercier 2012 (a crowd's speed from its density ahead)",
                  range=(0.0, 16.0)),
    _positive("empty_below", 0.5, "ped", "the room counts as empty when fewer than this "
              "many remain (the continuum never reaches exactly zero); t_evac_100 is then",
              range=(1e-6, 100.0)),
    _switch("dense_frames", 1, "1: steps run freely and each frame is interpolated in time "
            "between the two states around it; 0: steps land on every frame time"),
)

#: the finite-volume solver's numerics
FV_NUMERICS: tuple[Parameter, ...] = declare(
    Parameter("order", 3, "-", "3 CWENO3, 2 limited linear, 1 first order", kind="integer",
              choices=(1, 2, 3), cast=int),
    Parameter("cfl", None, "-", "dt = cfl min 2|T| / sum l alpha (None: the model's "
              "default)", low=0.0, high=1.0, high_closed=True, optional=True,
              range=(0.01, 1.0)),
    Parameter("exit", None, "", "exit condition (None: the model's default; vacuum, "
              "transmissive, godunov)", kind="text", optional=True),
    _switch("limiter", True, "Zhang-Shu point limiter and FCT flux limiter on the density",
            cast=bool),
    _non_negative("rho_eps", 0.0, "ped/m^2", "the FCT keeps every cell density >= this",
                  range=(0.0, 1.0)),
    _positive("eps_hat", 0.1, "-", "CWENO epsilon = (eps_hat q_ref h / 1 m)^2 (range: "
              "from weights that see every wiggle to the linear weights)", range=(1e-6, 1e6)),
    _switch("route_every_step", True, "re-solve the eikonal every step (at most every "
            "route_interval), else only at the start", cast=bool),
    Parameter("threads", None, "-", "threads of the compiled kernels, of either model "
              "(None: numba's count on large meshes and crowds, else 1)", kind="integer",
              low=1.0, low_closed=True, optional=True, cast=int, range=(1, 1024)),
    Parameter("implicit_pressure", None, "0/1", "semi-implicit step with the pressure "
              "implicit (None: on for every model with a pressure law in its flux)",
              kind="switch", optional=True, cast=bool),
    Parameter("stages", None, "-", "stages of the SSP Runge-Kutta step, 3 or 2 (None: 3 for "
              "an explicit pressure, else 2)", kind="integer", choices=(2, 3), optional=True,
              cast=int),
    _switch("active_set", True, "update only the cells near the crowd each step", cast=bool),
    _non_negative("active_eps", 1e-5, "ped/m^2", "density above which a cell counts as "
                  "occupied for the active set", range=(0.0, 1.0)),
)


def defaults(params: Iterable[Parameter] = TABLE1) -> Mapping[str, Any]:
    """``{name: default}`` of the given declarations (Table 1's by default)."""
    return {p.name: p.default for p in params}




#: ``{name: default}`` of every built-in parameter (read-only): the default arguments of the
#: classes and functions that take these quantities
DEFAULTS: Mapping[str, Any] = MappingProxyType(dict(defaults(PARAMETERS.values())))


# ---------------------------------------------------------------------- dataclass fields
def field(name: str, **kw) -> Any:
    """A dataclass field whose default and metadata come from the declaration of ``name``
    (``kw`` goes to :func:`dataclasses.field`)."""
    p = PARAMETERS[name]
    return dataclasses.field(default=p.default, metadata={"parameter": p}, **kw)


def check_fields(obj: Any, *, physical: bool = True) -> None:
    """Check (and cast) every field of a frozen dataclass made with :func:`field`, in field
    order (within the physical ranges unless ``physical`` is False)."""
    for f in dataclasses.fields(obj):
        p = f.metadata.get("parameter")
        if p is not None:
            object.__setattr__(obj, f.name, p.check(getattr(obj, f.name), physical=physical))


def check_values(values: Mapping[str, Any], params: Iterable[Parameter], *,
                 physical: bool = True) -> dict[str, Any]:
    """``values`` checked against the declarations ``params`` (by name; within the physical
    ranges unless ``physical`` is False); unknown names are an error naming the known
    ones."""
    known = {p.name: p for p in params}
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise ParameterError(f"unknown parameter '{unknown[0]}' "
                             f"(known: {', '.join(sorted(known))})")
    return {k: known[k].check(v, physical=physical) for k, v in values.items()}


def parse_overrides(items: Iterable[str] | None) -> dict[str, float | str]:
    """``["A=1500", "exit=transmissive"]`` -> ``{"A": 1500.0, "exit": "transmissive"}``,
    with clear errors: numbers must be finite; switches take 0/1/false/true (read as
    0.0/1.0); text parameters keep their words. Names not declared are read as numbers
    (the model then says they are unknown). A name given twice is refused."""
    out: dict[str, float | str] = {}
    seen: dict[str, str] = {}
    for item in items or []:
        if "=" not in item:
            raise ParameterError(f"--param expects NAME=VALUE, got '{item}'")
        name, _, value = item.partition("=")
        name = name.strip()
        if name in seen:  # refused rather than the last one silently winning
            raise ParameterError(f"parameter '{name}' is given twice ('{seen[name]}' and "
                                 f"'{item}'); give it once")
        seen[name] = item
        p = PARAMETERS.get(name)
        out[name] = _parse(name, value, p.kind if p is not None else "real")
    return out
