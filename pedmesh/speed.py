"""Desired-speed laws U_e(rho) = U_f g(rho): how fast people want to walk [m/s] at a local
density rho [ped/m^2], shared by the social force model and every continuum model.

* ``exponential`` (the paper's Table 1): ``g(rho) = exp(-beta rho)``, ``beta`` [m^2/ped].
  It never reaches zero: at 5 /m^2 people still want 78 % of their free speed (with
  beta = 0.05).
* ``weidmann`` (Weidmann 1993, the fundamental diagram of the RiMEA guideline and of most
  engineering tools): ``g(rho) = 1 - exp(-gamma_w (1/rho - 1/rho_jam))`` for
  ``0 < rho < rho_jam``, 1 at rho = 0 and 0 from the jam density ``rho_jam`` [ped/m^2] on;
  ``gamma_w`` [ped/m^2] sets how fast the speed falls (Weidmann: 1.913 /m^2, 5.4 /m^2,
  free speed 1.34 m/s).

Compiled kernels take the law as a small float64 array (:attr:`SpeedLaw.array`:
``[kind, beta, rho_jam, gamma_w, shift]``, the law evaluated at ``rho - shift``: the social
force model subtracts a pedestrian's own share of its kernel density with
``density_self=0``) and the free speed ``U_f`` separately (so that it can be
one number or one per pedestrian); :func:`shape` and :func:`flux_and_slope` evaluate it
inside them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from .errors import ParameterError

__all__ = ["SpeedLaw", "SPEED_LAWS", "EXPONENTIAL", "WEIDMANN", "shape", "flux_and_slope",
           "speed_law_from"]

#: the lowest speed, in units of U_f, that the route cost assumes of a jam
ROUTE_SPEED_FLOOR = 0.05
EXPONENTIAL = 0
WEIDMANN = 1
#: the laws by name (the ``speed_law`` parameter)
SPEED_LAWS = {"exponential": EXPONENTIAL, "weidmann": WEIDMANN}


@nb.njit(cache=True, error_model="numpy", fastmath={"contract"}, inline="always")
def shape(law, rho):
    """g(rho) = U_e(rho) / U_f of the law array ``law`` at density ``rho`` [ped/m^2]."""
    rho = rho - law[4]
    if law[0] == EXPONENTIAL:
        return math.exp(-law[1] * max(rho, 0.0))
    if rho <= 0.0:
        return 1.0
    if rho >= law[2]:
        return 0.0
    return 1.0 - math.exp(-law[3] * (1.0 / rho - 1.0 / law[2]))


@nb.njit(cache=True, error_model="numpy", fastmath={"contract"}, inline="always")
def flux_and_slope(law, U_f, rho):
    """The flow f(rho) = rho U_f g(rho - shift) [ped/(m s)] at rho = max(rho, 0) and
    |f'(rho)| [m/s]."""
    r = max(rho, 0.0)
    x = r - law[4]  # (below the shift: free flow)
    if law[0] == EXPONENTIAL:
        if x <= 0.0:
            return r * U_f, U_f
        e = math.exp(-law[1] * x)
        return r * U_f * e, abs(U_f * (1.0 - law[1] * r) * e)
    if x <= 0.0:
        return r * U_f, U_f
    if x >= law[2]:
        return 0.0, 0.0
    e = math.exp(-law[3] * (1.0 / x - 1.0 / law[2]))
    # f = U_f r (1 - e), f' = U_f (g + r g'(x)) with g' = -(gamma_w / x^2) e
    return U_f * r * (1.0 - e), abs(U_f * (1.0 - e - law[3] * r / (x * x) * e))


@dataclass(frozen=True)
class SpeedLaw:
    """A desired-speed law (see the module docstring): its name and parameters."""

    name: str = "exponential"
    U_f: float = 1.034  #: free speed [m/s]
    beta: float = 0.05  #: [m^2/ped] (exponential)
    rho_jam: float = 5.4  #: jam density [ped/m^2] (weidmann)
    gamma_w: float = 1.913  #: [ped/m^2] (weidmann)
    #: [ped/m^2] the law is evaluated at rho - shift (free flow below it): a continuum
    #: model's match to a social force model that feels U_e without its own kernel share
    shift: float = 0.0

    def __post_init__(self) -> None:
        if isinstance(self.shift, bool) or not isinstance(self.shift, (int, float)) or not (
                math.isfinite(self.shift) and self.shift >= 0):
            raise ParameterError(f"parameter 'rho_shift' must be >= 0, got {self.shift!r}")
        if self.name not in SPEED_LAWS:
            raise ParameterError(f"unknown speed law '{self.name}' (laws: "
                                 f"{', '.join(SPEED_LAWS)})")
        for k in ("U_f", "beta", "rho_jam", "gamma_w"):
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (
                    math.isfinite(v) and v > 0):
                raise ParameterError(f"parameter '{k}' must be positive, got {v!r}")

    @property
    def kind(self) -> int:
        return SPEED_LAWS[self.name]

    @property
    def array(self) -> np.ndarray:
        """``[kind, beta, rho_jam, gamma_w, shift]`` for the compiled kernels."""
        return np.array([self.kind, self.beta, self.rho_jam, self.gamma_w, self.shift], float)

    def __call__(self, rho) -> np.ndarray:
        """U_e(rho) [m/s]."""
        return self.U_f * self.shape(rho)

    def shape(self, rho) -> np.ndarray:
        """g(rho) = U_e(rho) / U_f."""
        r = np.maximum(np.asarray(rho, float) - self.shift, 0.0)
        if self.kind == EXPONENTIAL:
            return np.exp(-self.beta * r)
        with np.errstate(divide="ignore", over="ignore"):
            g = 1.0 - np.exp(-self.gamma_w * (1.0 / r - 1.0 / self.rho_jam))
        return np.where(r <= 0, 1.0, np.where(r >= self.rho_jam, 0.0, g))

    def route_cost(self, rho) -> np.ndarray:
        """The eikonal cost 1/U_e(rho) [s/m] of the route; with a jam density, U_e is
        taken no lower than ``ROUTE_SPEED_FLOOR`` U_f (a jam is slow to cross, not a wall)."""
        if self.kind == EXPONENTIAL:
            return 1.0 / self(rho)
        return 1.0 / np.maximum(self(rho), ROUTE_SPEED_FLOOR * self.U_f)

    def flow(self, rho) -> np.ndarray:
        """f(rho) = rho U_e(rho) [ped/(m s)]."""
        r = np.maximum(np.asarray(rho, float), 0.0)
        return r * self(r)

    @property
    def capacity_density(self) -> float:
        """The density [ped/m^2] of the largest flow (1/beta for the exponential law)."""
        if self.kind == EXPONENTIAL and 1.0 / self.beta >= self.shift:
            return 1.0 / self.beta
        from scipy.optimize import minimize_scalar

        top = self.shift + (self.rho_jam if self.kind == WEIDMANN else 10.0 / self.beta)
        res = minimize_scalar(lambda r: -float(self.flow(r)), bounds=(1e-6, top),
                              method="bounded", options={"xatol": 1e-10})
        return float(res.x)

    @property
    def capacity(self) -> float:
        """The largest flow [ped/(m s)]: a saturated exit's capacity per metre of width."""
        return float(self.flow(self.capacity_density))

    def parameters(self) -> dict[str, float | str]:
        """The parameters this law uses (for summaries)."""
        extra = {"rho_shift": self.shift} if self.shift else {}
        if self.kind == EXPONENTIAL:
            return {"speed_law": self.name, "U_f": self.U_f, "beta": self.beta, **extra}
        return {"speed_law": self.name, "U_f": self.U_f, "rho_jam": self.rho_jam,
                "gamma_w": self.gamma_w, **extra}


def speed_law_from(params) -> SpeedLaw:
    """The :class:`SpeedLaw` of an object or mapping with ``speed_law``, ``U_f``, ``beta``,
    ``rho_jam``, ``gamma_w`` (missing ones: the defaults)."""
    get = params.get if isinstance(params, dict) else (lambda k, d: getattr(params, k, d))
    d = SpeedLaw()
    return SpeedLaw(name=get("speed_law", d.name), U_f=get("U_f", d.U_f),
                    beta=get("beta", d.beta), rho_jam=get("rho_jam", d.rho_jam),
                    gamma_w=get("gamma_w", d.gamma_w))
