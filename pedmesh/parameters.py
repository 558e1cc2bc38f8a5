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

__all__ = ["Parameter", "PARAMETERS", "TABLE1", "TABLE1_SOURCE", "DEFAULT_T_END_S", "DEFAULTS",
           "declare", "get", "field", "check_fields", "check_values", "parse_overrides",
           "defaults"]

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
    ``low_closed``/``high_closed``. ``optional``: None is allowed (the model derives the
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

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"parameter kind must be one of {KINDS}, got {self.kind!r}")

    # ------------------------------------------------------------------ checks
    @property
    def bounds(self) -> str:
        """The allowed values in words (for messages and tables)."""
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

    def check(self, value: Any) -> Any:
        """``value`` checked (and cast); a one-line :class:`~pedmesh.errors.ParameterError`
        naming the parameter otherwise."""
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
            if self.kind == "integer" and value != int(value):
                raise ParameterError(f"parameter '{name}' must be a whole number "
                                     f"{self.bounds}, got {value!r}")
            lo_bad = self.low is not None and (value < self.low if self.low_closed
                                               else not value > self.low)
            hi_bad = self.high is not None and (value > self.high if self.high_closed
                                                else not value < self.high)
            if lo_bad or hi_bad:
                what = self.bounds
                if self.kind == "integer":
                    what = "a whole number " + what
                raise ParameterError(f"parameter '{name}' must be {what}, got {value!r}")
        return self.cast(value) if self.cast else value

    def parse(self, text: str) -> Any:
        """The value of ``--param NAME=TEXT``: words for text parameters, 0/1/false/true for
        switches (read as 0.0/1.0), numbers otherwise (checked for finiteness here, against
        the bounds by :meth:`check` when the model is built)."""
        return _parse(self.name, text, self.kind)

    def row(self) -> dict[str, Any]:
        """The declaration as a table row (``pedmesh presets``, the documentation)."""
        return {"name": self.name, "default": self.default, "unit": self.unit,
                "bounds": self.bounds, "description": self.description,
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


#: the paper's Table 1: the social force model's physics, and the continuum models' where
#: they take the same quantity
TABLE1: tuple[Parameter, ...] = declare(
    _positive("U_f", 1.034, "m/s", "free-flow (desired) speed U_f", TABLE1_SOURCE),
    _positive("beta", 0.05, "m^2/ped", "speed-density parameter of the exponential law "
              "U_e = U_f exp(-beta rho)", TABLE1_SOURCE),
    _positive("tau", 0.5, "s", "relaxation time tau of the driving force (and of the "
              "continuum models' momentum relaxation)", TABLE1_SOURCE),
    _positive("m", 60.0, "kg", "pedestrian mass m", TABLE1_SOURCE),
    _positive("r", 0.15, "m", "body radius r_i (so r_ij = 2 r = 0.3 m)", TABLE1_SOURCE),
    _positive("R", 0.7, "m", "width of the Gaussian density kernel R (eq4)", TABLE1_SOURCE),
    _positive("A", 2000.0, "N", "strength of the social repulsion A", TABLE1_SOURCE),
    _positive("B", 0.08, "m", "range of the social repulsion B", TABLE1_SOURCE),
    _positive("k", 1.2e5, "kg/s^2", "body (contact) force constant k", TABLE1_SOURCE),
    _positive("kappa", 2.4e5, "kg/(m s)", "sliding friction constant kappa", TABLE1_SOURCE),
)

#: the desired-speed law U_e(rho) (:mod:`pedmesh.speed`) besides U_f and beta
SPEED_LAW: tuple[Parameter, ...] = declare(
    Parameter("speed_law", "exponential", "",
              "the desired-speed law: 'exponential' (the paper's, U_f exp(-beta rho)), "
              "'weidmann' (U_f (1 - exp(-gamma_w (1/rho - 1/rho_jam)))) or 'table' (U_f "
              "g(rho), g piecewise linear through the points of speed_table)",
              TABLE1_SOURCE, kind="text"),
    _positive("rho_jam", 5.4, "ped/m^2", "jam density of the Weidmann law", WEIDMANN_SOURCE),
    _positive("gamma_w", 1.913, "ped/m^2", "how fast the Weidmann law's speed falls",
              WEIDMANN_SOURCE),
    Parameter("speed_table", "", "ped/m^2 : -",
              "the points 'rho:g rho:g ...' (density : U_e/U_f) of the 'table' law",
              kind="text"),
    _non_negative("rho_shift", 0.0, "ped/m^2", "the law is read at rho - rho_shift (the "
                  "continuum models' copy of the social force model's own-share shift)"),
)

#: the social force model's terms beyond Table 1 (off by default: the paper's model)
SFM_TERMS: tuple[Parameter, ...] = declare(
    _switch("density_self", 1.0, "1: U_e at the kernel density with the pedestrian's own "
            "share, as in the paper (eq3: a lone walker feels 1/(pi R^2) = 0.65 /m^2); 0: "
            "without it (a lone walker walks at U_f)", TABLE1_SOURCE + " (eq3)"),
    _non_negative("shrink", 0.0, "m", "speed-dependent space requirement: a person whose "
                  "desired speed is 0 keeps a social radius this much smaller than the body "
                  "radius r (0: off, the paper's model); body contact acts on the body radii"),
    _positive("t_space", 1.06, "s", "the social radius grows by t_space/2 per m/s of the "
              "desired speed, back to r", "Seyfried et al. 2005: a walker needs 0.36 m + "
              "1.06 s x v"),
    Parameter("vision", 1.0, "-", "field of vision (Helbing's lambda): the social repulsion "
              "of someone straight behind counts this much, straight ahead fully (1: "
              "isotropic, the paper's model)", "Helbing & Molnar 1995; Helbing et al. 2000",
              low=0.0, high=1.0, low_closed=True, high_closed=True),
    Parameter("crowd_stretch", 1.0, "-", "queueing or crowding: where the free width is at "
              "least crowd_width, the speed law above crowd_knee is read at densities this "
              "many times lower (1: off, the paper's model)", ADRIAN_SOURCE, low=1.0,
              low_closed=True),
    _positive("crowd_knee", 2.7, "ped/m^2", "the density above which crowding stretches the "
              "speed law"),
    _positive("queue_width", 1.2, "m", "free widths up to this queue (crowding factor 0)",
              ADRIAN_SOURCE),
    _positive("crowd_width", 2.3, "m", "free widths from this on crowd (crowding factor 1)",
              ADRIAN_SOURCE),
)

#: the social force model's numerics
SFM_NUMERICS: tuple[Parameter, ...] = declare(
    _positive("dt", 0.01, "s", "time step of the SSP-RK3 integrator"),
    _non_negative("route_interval", 1.0, "s", "interval between re-solves of the route "
                  "potential (0: every step; the direction is held in between)"),
    _positive("force_cutoff", 1.2, "m", "interaction cut-off: A exp((0.3 - 1.2)/0.08) = "
              "0.026 N, 2e-4 of the driving force m U_f / tau = 124 N"),
    _positive("density_cutoff", 3.0, "R", "density-kernel cut-off in units of R: "
              "exp(-3^2) = 1.2e-4 of the kernel mass is cut"),
    Parameter("density_stages", 1, "-", "RK stages at which the kernel density (hence U_e) "
              "is evaluated: 1 = once per step, at its start; 3 = at every stage",
              kind="integer", choices=(1, 3), cast=int),
    _positive("max_speed", 10.0, "m/s", "a speed above this stops the run as a blow-up"),
    _non_negative("overlap_tolerance", 0.05, "m", "initial pedestrians may overlap their "
                  "bodies by at most this much"),
)

#: output and stopping settings every model has
RUN_OUTPUT: tuple[Parameter, ...] = declare(
    _positive("output_interval", 1.0, "s", "interval between density (and pedestrian) "
              "frames"),
    _positive("sample_interval", 0.1, "s", "interval between rows of evacuation.csv and "
              "outflow.csv"),
)

#: the continuum models' physics beyond Table 1 and the speed law
CONTINUUM: tuple[Parameter, ...] = declare(
    _non_negative("c0", 1.0, "m/s", "Payne-Whitham's sound speed (momentum flux rho u u + "
                  "c0^2 rho)", "Payne 1971; Whitham 1974"),
    _positive("rho_cut", 1e-3, "ped/m^2", "below this density a film moves at its own "
              "velocity (first order), so it drains"),
    _positive("u_max", None, "m/s", "largest speed (None: the model's default multiple of "
              "U_f, 2.5 U_f, 1.5 U_f for eos)", optional=True),
    _switch("walls", 1.0, "mac1: the walls repel, as the social force model's do"),
    _switch("friction", 1.0, "mac1: the sliding-friction term"),
    _positive("cutoff", 1.0, "m", "mac1: cut-off of the nonlocal kernels (must exceed the "
              "body diameter)"),
    _switch("split_friction", 1.0, "mac1: the stiff friction by Strang splitting around "
            "each step (0: inside the stages, cfl 0.4)"),
    _switch("imex", 1.0, "mac1: the local part of the repulsion as a pressure, implicit "
            "(0: the explicit scheme)"),
    _positive("lr_strength", 0.01, "-", "mac2: strength of the long-range repulsion"),
    _positive("lr_length", 1.0, "m", "mac2: length of the long-range repulsion"),
    _positive("gamma1", None, "N m^4/(kg ped)", "mac2: the local pressure coefficient "
              "(None: from the Table 1 repulsion)", optional=True),
    Parameter("calibration", None, "", "eos: the equation-of-state file written by "
              "`pedmesh calibrate` (None: the one shipped for Table 1)", kind="text",
              optional=True),
    _positive("empty_below", 0.5, "ped", "the room counts as empty when fewer than this "
              "many remain (the continuum never reaches exactly zero); t_evac_100 is then"),
    _switch("dense_frames", 1, "1: steps run freely and each frame is interpolated in time "
            "between the two states around it; 0: steps land on every frame time"),
)

#: the finite-volume solver's numerics
FV_NUMERICS: tuple[Parameter, ...] = declare(
    Parameter("order", 3, "-", "3 CWENO3, 2 limited linear, 1 first order", kind="integer",
              choices=(1, 2, 3), cast=int),
    Parameter("cfl", None, "-", "dt = cfl min 2|T| / sum l alpha (None: the model's "
              "default)", low=0.0, high=1.0, high_closed=True, optional=True),
    Parameter("exit", None, "", "exit condition (None: the model's default; vacuum, "
              "transmissive, godunov)", kind="text", optional=True),
    _switch("limiter", True, "Zhang-Shu point limiter and FCT flux limiter on the density",
            cast=bool),
    _non_negative("rho_eps", 0.0, "ped/m^2", "the FCT keeps every cell density >= this"),
    _positive("eps_hat", 0.1, "-", "CWENO epsilon = (eps_hat q_ref h / 1 m)^2"),
    _switch("route_every_step", True, "re-solve the eikonal every step (at most every "
            "route_interval), else only at the start", cast=bool),
    Parameter("threads", None, "-", "threads of the compiled kernels (None: numba's count "
              "on large meshes, else 1)", kind="integer", low=1.0, low_closed=True,
              optional=True, cast=int),
    Parameter("implicit_pressure", None, "0/1", "semi-implicit step with the pressure "
              "implicit (None: on for every model with a pressure law in its flux)",
              kind="switch", optional=True, cast=bool),
    Parameter("stages", None, "-", "stages of the SSP Runge-Kutta step, 3 or 2 (None: 3 for "
              "an explicit pressure, else 2)", kind="integer", choices=(2, 3), optional=True,
              cast=int),
    _switch("active_set", True, "update only the cells near the crowd each step", cast=bool),
    _non_negative("active_eps", 1e-5, "ped/m^2", "density above which a cell counts as "
                  "occupied for the active set"),
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


def check_fields(obj: Any) -> None:
    """Check (and cast) every field of a frozen dataclass made with :func:`field`, in field
    order."""
    for f in dataclasses.fields(obj):
        p = f.metadata.get("parameter")
        if p is not None:
            object.__setattr__(obj, f.name, p.check(getattr(obj, f.name)))


def check_values(values: Mapping[str, Any], params: Iterable[Parameter]) -> dict[str, Any]:
    """``values`` checked against the declarations ``params`` (by name); unknown names are
    an error naming the known ones."""
    known = {p.name: p for p in params}
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise ParameterError(f"unknown parameter '{unknown[0]}' "
                             f"(known: {', '.join(sorted(known))})")
    return {k: known[k].check(v) for k, v in values.items()}


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
