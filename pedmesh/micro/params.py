"""Parameters of the social force model (paper Table 1) and of its numerics.

Every field carries its SI unit and the paper's symbol. Both dataclasses are frozen;
:func:`with_overrides` builds new ones from ``NAME=VALUE`` strings (the CLI's ``--param``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields
from typing import Any, Iterable

from ..errors import ParameterError
from .crowding import CROWD_WIDTH_M, QUEUE_WIDTH_M

__all__ = ["SocialForceParams", "SFMNumerics", "with_overrides", "parse_param_overrides",
           "TEXT_PARAMS", "BOOL_PARAMS"]


@dataclass(frozen=True, kw_only=True)
class SocialForceParams:
    """Physical parameters of the social force model (paper Table 1 defaults)."""

    m: float = 60.0  #: pedestrian mass [kg], m
    tau: float = 0.5  #: relaxation time [s], tau
    beta: float = 0.05  #: speed-density parameter [m^2/ped], beta in U_e = U_f exp(-beta rho)
    U_f: float = 1.034  #: free-flow speed [m/s], U_f
    R: float = 0.7  #: width of the Gaussian density kernel [m], R (eq4)
    A: float = 2000.0  #: strength of the social repulsion [N], A
    B: float = 0.08  #: range of the social repulsion [m], B
    r: float = 0.15  #: body radius [m], r_i (so r_ij = 2 r = 0.3 m)
    k: float = 1.2e5  #: body (contact) force constant [kg/s^2], k
    kappa: float = 2.4e5  #: sliding friction constant [kg/(m s)], kappa
    #: the desired-speed law U_e(rho) (:mod:`pedmesh.speed`): 'exponential' (the paper's,
    #: U_f exp(-beta rho)), 'weidmann' (U_f (1 - exp(-gamma_w (1/rho - 1/rho_jam)))) or
    #: 'table' (U_f g(rho), g piecewise linear through the points of ``speed_table``)
    speed_law: str = "exponential"
    rho_jam: float = 5.4  #: jam density [ped/m^2] of the Weidmann law
    gamma_w: float = 1.913  #: [ped/m^2] of the Weidmann law
    #: the points "rho:g rho:g ..." (density [ped/m^2] : U_e/U_f) of the 'table' law
    speed_table: str = ""
    #: 1: U_e is evaluated at the kernel density with the pedestrian's own share, as in the
    #: paper (eq3: a lone walker feels 1/(pi R^2) = 0.65 /m^2); 0: without it (a lone
    #: walker walks at U_f)
    density_self: float = 1.0
    #: [m] speed-dependent space requirement: a person whose desired speed is 0 keeps a
    #: social radius this much smaller than the body radius r (0: off, the paper's model);
    #: the social repulsion acts from the sum of two social radii, body contact from the
    #: body radii
    shrink: float = 0.0
    #: [s] the social radius grows by t_space/2 per m/s of the desired speed U_e, back to r
    #: (Seyfried et al. 2005: a walker needs 0.36 m + 1.06 s x v)
    t_space: float = 1.06
    #: [-] field of vision (Helbing's lambda): the social repulsion of someone straight
    #: behind counts this much, of someone straight ahead fully, (1 + lambda)/2 beside (1:
    #: isotropic, the paper's model); body contact is always isotropic
    vision: float = 1.0
    #: [-] queueing or crowding (:mod:`pedmesh.micro.crowding`): for a pedestrian in a space
    #: at least 2.3 m wide (crowding), the speed law's part above ``crowd_knee`` is read at
    #: densities this many times lower, so a crowd presses on where a queue (in a corridor
    #: 1.2 m wide or less) stands; in between, in proportion (1: off, the paper's model)
    crowd_stretch: float = 1.0
    #: [ped/m^2] the density above which crowding stretches the speed law
    crowd_knee: float = 2.7
    #: [m] free widths up to this queue (crowding factor 0; Adrian et al. 2020: the change
    #: from queueing to crowding lies between corridors 1.2 and 2.3 m wide)
    queue_width: float = QUEUE_WIDTH_M
    #: [m] free widths from this on crowd (crowding factor 1)
    crowd_width: float = CROWD_WIDTH_M

    def __post_init__(self) -> None:
        _check_positive(self, skip=("speed_law", "density_self", "speed_table", "shrink",
                                    "vision"))
        if not (isinstance(self.vision, (int, float)) and not isinstance(self.vision, bool)
                and 0.0 <= self.vision <= 1.0):
            raise ParameterError(f"parameter 'vision' must be in [0, 1], got {self.vision!r}")
        if not self.crowd_width > self.queue_width:
            raise ParameterError(f"parameter 'crowd_width' ({self.crowd_width!r} m) must be "
                                 f"larger than 'queue_width' ({self.queue_width!r} m)")
        if not self.crowd_stretch >= 1.0:
            raise ParameterError(f"parameter 'crowd_stretch' must be >= 1, got "
                                 f"{self.crowd_stretch!r}")
        if not (isinstance(self.shrink, (int, float)) and not isinstance(self.shrink, bool)
                and 0.0 <= self.shrink < self.r):
            raise ParameterError(f"parameter 'shrink' must be >= 0 and less than the body "
                                 f"radius r = {self.r:g} m, got {self.shrink!r}")
        if self.density_self not in (0, 1) or isinstance(self.density_self, bool):
            raise ParameterError(f"parameter 'density_self' must be 0 or 1, got "
                                 f"{self.density_self!r}")
        self.speed  # (checks the law's name)

    @property
    def speed(self):
        """The desired-speed law (:class:`pedmesh.speed.SpeedLaw`)."""
        from ..speed import SpeedLaw

        return SpeedLaw(self.speed_law, self.U_f, self.beta, self.rho_jam, self.gamma_w,
                        table=self.speed_table)

    def kernel_law(self):
        """The speed law array (:func:`pedmesh.speed.shape`) the social force model reads
        at its Gaussian kernel density, which includes one's own share: with
        ``density_self`` 0 the law is shifted by that share, 1/(pi R^2)."""
        law = self.speed.array
        if not self.density_self:
            law[4] = 1.0 / (math.pi * self.R * self.R)
        return law

    def desired_speed(self, rho):
        """U_e(rho) [m/s] (paper eq_desired_speed: U_f exp(-beta rho) with the exponential
        law)."""
        return self.speed(rho)


@dataclass(frozen=True, kw_only=True)
class SFMNumerics:
    """Numerical settings of a social force run.

    The defaults were chosen by convergence checks (see ``benchmarks/sfm.py`` and the
    README): halving ``dt`` or re-solving the routes every step changes the evacuation
    curve of the paper's Example 2 by less than 1 %.
    """

    dt: float = 0.01  #: time step [s] of the SSP-RK3 integrator
    #: interval [s] between re-solves of the route potential (0 = every step)
    route_interval: float = 1.0
    #: interaction cut-off [m]: A exp((0.3 - 1.2)/0.08) = 0.026 N, 2e-4 of the driving
    #: force m U_f / tau = 124 N
    force_cutoff: float = 1.2
    #: density-kernel cut-off in units of R: exp(-3^2) = 1.2e-4 of the kernel mass is cut
    density_cutoff: float = 3.0
    #: RK stages at which the kernel density rho_loc (hence U_e) is evaluated: 1 = once per
    #: step, at its start, and held over the three stages (the default: a 0.01 s hold, far
    #: shorter than the 1 s route hold, and the Example 2 evacuation curve moves by less
    #: than 0.1 %, see the README); 3 = at every stage
    density_stages: int = 1
    #: a speed above this [m/s] stops the run as a blow-up
    max_speed: float = 10.0
    #: interval [s] between output frames (VTK, trajectories)
    output_interval: float = 1.0
    #: interval [s] between rows of evacuation.csv
    sample_interval: float = 0.1
    #: initial pedestrians may overlap their bodies by at most this much [m]
    overlap_tolerance: float = 0.05

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
                raise ParameterError(f"parameter '{f.name}' must be a finite number, got {v!r}")
        for name in ("dt", "force_cutoff", "density_cutoff", "max_speed", "output_interval",
                     "sample_interval"):
            if not getattr(self, name) > 0:
                raise ParameterError(f"parameter '{name}' must be positive, "
                                     f"got {getattr(self, name)!r}")
        if self.density_stages not in (1, 3):
            raise ParameterError(
                f"parameter 'density_stages' must be 1 or 3, got {self.density_stages!r}")
        object.__setattr__(self, "density_stages", int(self.density_stages))  # 3.0 -> 3
        for name in ("route_interval", "overlap_tolerance"):
            if getattr(self, name) < 0:
                raise ParameterError(f"parameter '{name}' must be >= 0, "
                                     f"got {getattr(self, name)!r}")


def _check_positive(obj: Any, skip: tuple[str, ...] = ()) -> None:
    for f in fields(obj):
        if f.name in skip:
            continue
        v = getattr(obj, f.name)
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
            raise ParameterError(f"parameter '{f.name}' must be a finite number, got {v!r}")
        if not v > 0:
            raise ParameterError(f"parameter '{f.name}' must be positive, got {v!r}")


#: parameters whose values are words, not numbers
TEXT_PARAMS = {"exit", "calibration", "speed_law", "speed_table"}
#: switches: 0/1 or false/true on the command line (read as 0.0/1.0)
BOOL_PARAMS = {"limiter", "route_every_step", "walls", "friction", "split_friction", "imex",
               "density_self"}
_BOOL_WORDS = {"0": 0.0, "1": 1.0, "false": 0.0, "true": 1.0}


def parse_param_overrides(items: Iterable[str]) -> dict[str, float | str]:
    """``["A=1500", "exit=transmissive"]`` -> ``{"A": 1500.0, "exit": "transmissive"}``,
    with clear errors: numbers must be finite; the switches in :data:`BOOL_PARAMS` take
    0/1/false/true (read as 0.0/1.0)."""
    out: dict[str, float | str] = {}
    for item in items or []:
        if "=" not in item:
            raise ParameterError(f"--param expects NAME=VALUE, got '{item}'")
        name, _, value = item.partition("=")
        name = name.strip()
        if name in TEXT_PARAMS:
            out[name] = value.strip()
            continue
        if name in BOOL_PARAMS:
            word = value.strip().lower()
            try:  # 0, 1, 0.0, 1e0 ... as numbers
                word = {0.0: "0", 1.0: "1"}.get(float(word), word)
            except ValueError:
                pass
            if word not in _BOOL_WORDS:
                raise ParameterError(f"parameter '{name}' must be 0 or 1 (or false/true), "
                                     f"got '{value.strip()}'")
            out[name] = _BOOL_WORDS[word]
            continue
        try:
            out[name] = float(value)
        except ValueError:
            raise ParameterError(f"parameter '{name}': '{value}' is not a number") from None
        if not math.isfinite(out[name]):
            raise ParameterError(f"parameter '{name}' must be a finite number, "
                                 f"got {value.strip()}")
    return out


def with_overrides(overrides: dict[str, float], *classes_and_defaults) -> list:
    """Split ``overrides`` over the given dataclass instances; unknown names are an error."""
    known = {f.name for obj in classes_and_defaults for f in fields(obj)}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise ParameterError(
            f"unknown parameter '{unknown[0]}' (known: {', '.join(sorted(known))})"
        )
    out = []
    for obj in classes_and_defaults:
        mine = {k: v for k, v in overrides.items() if k in {f.name for f in fields(obj)}}
        out.append(dataclasses.replace(obj, **mine))
    return out
