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
* ``table``: ``g`` piecewise linear through given points ``(rho_k, g_k)`` (the parameter
  ``speed_table``, e.g. ``"0:1 0.7:1 1:0.92 ... 5.6:0"``: density [ped/m^2] : g [-]),
  constant beyond the last one: a measured fundamental diagram. The densities must start
  at 0 with g = 1 and increase; g must not increase and lie in [0, 1].

Compiled kernels take the law as a small float64 array (:attr:`SpeedLaw.array`:
``[kind, beta, rho_jam, gamma_w, shift, n, rho_1..rho_n, g_1..g_n]`` (n = 0 but for
``table``), the law evaluated at ``rho - shift``: the social
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
from .parameters import DEFAULTS as D

__all__ = ["cone_norm", "SpeedLaw", "SPEED_LAWS", "EXPONENTIAL", "WEIDMANN", "TABLE", "shape",
           "flux_and_slope", "speed_law_from", "parse_speed_table", "format_speed_table"]

#: the lowest speed, in units of U_f, that the route cost assumes of a jam
ROUTE_SPEED_FLOOR = 0.05
EXPONENTIAL = 0
WEIDMANN = 1
TABLE = 2
#: the laws by name (the ``speed_law`` parameter)
SPEED_LAWS = {"exponential": EXPONENTIAL, "weidmann": WEIDMANN, "table": TABLE}
#: where a law array's table starts (its number of points is at index 5)
_T0 = 6


@nb.njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"}, inline="always")
def _table(law, x):
    """g(x) and g'(x) of a ``table`` law array at x [ped/m^2] (piecewise linear, constant
    beyond the last point; x >= 0)."""
    n = int(law[5])
    xs = law[_T0:_T0 + n]
    gs = law[_T0 + n:_T0 + 2 * n]
    if x >= xs[n - 1]:
        return gs[n - 1], 0.0
    k = 0
    while xs[k + 1] <= x:
        k += 1
    slope = (gs[k + 1] - gs[k]) / (xs[k + 1] - xs[k])
    return gs[k] + slope * (x - xs[k]), slope


@nb.njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"}, inline="always")
def shape(law, rho):
    """g(rho) = U_e(rho) / U_f of the law array ``law`` at density ``rho`` [ped/m^2]."""
    rho = rho - law[4]
    if law[0] == EXPONENTIAL:
        return math.exp(-law[1] * max(rho, 0.0))
    if law[0] == TABLE:
        return _table(law, max(rho, 0.0))[0]
    if rho <= 0.0:
        return 1.0
    if rho >= law[2]:
        return 0.0
    return 1.0 - math.exp(-law[3] * (1.0 / rho - 1.0 / law[2]))


@nb.njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"}, inline="always")
def flux_and_slope(law, U_f, rho):
    """The flow f(rho) = rho U_f g(rho - shift) [ped/(m s)] at rho = max(rho, 0) and
    ``|f'(rho)|`` [m/s]."""
    r = max(rho, 0.0)
    x = r - law[4]  # (below the shift: free flow)
    if law[0] == EXPONENTIAL:
        if x <= 0.0:
            return r * U_f, U_f
        e = math.exp(-law[1] * x)
        return r * U_f * e, abs(U_f * (1.0 - law[1] * r) * e)
    if x <= 0.0:
        return r * U_f, U_f
    if law[0] == TABLE:
        g, dg = _table(law, x)
        return U_f * r * g, abs(U_f * (g + r * dg))
    if x >= law[2]:
        return 0.0, 0.0
    e = math.exp(-law[3] * (1.0 / x - 1.0 / law[2]))
    # f = U_f r (1 - e), f' = U_f (g + r g'(x)) with g' = -(gamma_w / x^2) e
    return U_f * r * (1.0 - e), abs(U_f * (1.0 - e - law[3] * r / (x * x) * e))


@dataclass(frozen=True)
class SpeedLaw:
    """A desired-speed law (see the module docstring): its name and parameters."""

    name: str = "exponential"
    U_f: float = D['U_f']  #: free speed [m/s]
    beta: float = D['beta']  #: [m^2/ped] (exponential)
    rho_jam: float = D['rho_jam']  #: jam density [ped/m^2] (weidmann)
    gamma_w: float = D['gamma_w']  #: [ped/m^2] (weidmann)
    #: [ped/m^2] the law is evaluated at rho - shift (free flow below it): a continuum
    #: model's match to a social force model that feels U_e without its own kernel share
    shift: float = 0.0
    #: the points (rho [ped/m^2], g) of the ``table`` law: a sequence of pairs or the text
    #: ``"rho:g rho:g ..."`` (commas or spaces between the pairs); read as a tuple of pairs
    table: object = ()

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
        object.__setattr__(self, "table", parse_speed_table(self.table))
        if self.name == "table" and not self.table:
            raise ParameterError("speed law 'table' needs its points: parameter "
                                 "'speed_table', e.g. \"0:1 1:0.9 3:0.3 5.4:0\"")

    @property
    def kind(self) -> int:
        return SPEED_LAWS[self.name]

    @property
    def array(self) -> np.ndarray:
        """``[kind, beta, rho_jam, gamma_w, shift, n, rho_1..rho_n, g_1..g_n]`` for the
        compiled kernels (n = 0 but for the ``table`` law)."""
        pts = np.asarray(self.table if self.kind == TABLE else [], float).reshape(-1, 2)
        return np.concatenate([[self.kind, self.beta, self.rho_jam, self.gamma_w, self.shift,
                                len(pts)], pts[:, 0], pts[:, 1]]).astype(float)

    @property
    def jam_density(self) -> float:
        """The density [ped/m^2] from which g = 0 (inf for a law that never stops),
        without the shift."""
        if self.kind == WEIDMANN:
            return self.rho_jam
        if self.kind == TABLE:
            zero = [x for x, g in self.table if g == 0.0]
            return zero[0] if zero else math.inf
        return math.inf

    def __call__(self, rho) -> np.ndarray:
        """U_e(rho) [m/s]."""
        return self.U_f * self.shape(rho)

    def shape(self, rho) -> np.ndarray:
        """g(rho) = U_e(rho) / U_f."""
        r = np.maximum(np.asarray(rho, float) - self.shift, 0.0)
        if self.kind == EXPONENTIAL:
            return np.exp(-self.beta * r)
        if self.kind == TABLE:
            x, g = np.asarray(self.table, float).T
            return np.interp(r, x, g)  # (constant beyond the last point)
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
        if self.kind == TABLE:
            return self._table_capacity_density()
        from scipy.optimize import minimize_scalar

        if self.kind == WEIDMANN:
            top = self.shift + self.rho_jam
        else:
            top = self.shift + 10.0 / self.beta
        res = minimize_scalar(lambda r: -float(self.flow(r)), bounds=(1e-6, top),
                              method="bounded", options={"xatol": 1e-10})
        return float(res.x)

    def _table_capacity_density(self) -> float:
        """The ``table`` law's capacity density, exactly: on each segment the flow
        (x + shift) U_f g(x) is a quadratic in x, so its largest value is at a segment's end
        or at the quadratic's vertex."""
        if self.table[-1][1] > 0.0:
            raise ParameterError(
                f"speed_table {format_speed_table(self.table)!r} never reaches g = 0, so its "
                f"flow rho U_e(rho) has no largest value: end it with a jam point rho:0")
        best, arg = -1.0, 0.0
        for (x0, g0), (x1, g1) in zip(self.table, self.table[1:]):
            s = (g1 - g0) / (x1 - x0)
            cands = [x0, x1]
            if s < 0.0:  # d/dx [(x + shift)(g0 + s (x - x0))] = 0
                xv = (s * x0 - g0 - s * self.shift) / (2.0 * s)
                if x0 < xv < x1:
                    cands.append(xv)
            for x in cands:
                f = (x + self.shift) * (g0 + s * (x - x0))
                if f > best:
                    best, arg = f, x + self.shift
        return float(arg)

    @property
    def capacity(self) -> float:
        """The largest flow [ped/(m s)]: a saturated exit's capacity per metre of width."""
        return float(self.flow(self.capacity_density))

    def parameters(self) -> dict[str, float | str]:
        """The parameters this law uses (for summaries)."""
        extra = {"rho_shift": self.shift} if self.shift else {}
        if self.kind == EXPONENTIAL:
            return {"speed_law": self.name, "U_f": self.U_f, "beta": self.beta, **extra}
        if self.kind == TABLE:
            return {"speed_law": self.name, "U_f": self.U_f,
                    "speed_table": format_speed_table(self.table), **extra}
        return {"speed_law": self.name, "U_f": self.U_f, "rho_jam": self.rho_jam,
                "gamma_w": self.gamma_w, **extra}


def parse_speed_table(table) -> tuple[tuple[float, float], ...]:
    """The points ``((rho, g), ...)`` of a ``table`` law from pairs or the text
    ``"rho:g rho:g ..."``; a :class:`~pedmesh.errors.ParameterError` naming the problem
    unless they start at (0, 1), the densities increase and g does not, within [0, 1]."""
    if table is None or (isinstance(table, str) and not table.strip()):
        return ()
    try:
        if isinstance(table, str):
            pts = [tuple(float(v) for v in item.split(":"))
                   for item in table.replace(",", " ").split()]
        else:
            pts = [tuple(float(v) for v in p) for p in table]
    except (TypeError, ValueError):
        raise ParameterError(f"parameter 'speed_table' must be points rho:g (density "
                             f"[ped/m^2] : fraction of U_f), got {table!r}") from None
    if not pts:
        return ()
    if any(len(p) != 2 or not all(math.isfinite(v) for v in p) for p in pts):
        raise ParameterError(f"parameter 'speed_table' must be points rho:g of two finite "
                             f"numbers, got {table!r}")
    if pts[0] != (0.0, 1.0):
        raise ParameterError(f"parameter 'speed_table' must start at 0:1 (free speed at "
                             f"density 0), got {pts[0][0]:g}:{pts[0][1]:g}")
    for (x0, g0), (x1, g1) in zip(pts, pts[1:]):
        if not x1 > x0:
            raise ParameterError(f"parameter 'speed_table': densities must increase, got "
                                 f"{x1:g} after {x0:g}")
        if g1 > g0 or g1 < 0.0:
            raise ParameterError(f"parameter 'speed_table': g must not increase and stay "
                                 f"in [0, 1], got {g1:g} after {g0:g} at {x1:g} /m^2")
    if len(pts) < 2:
        raise ParameterError("parameter 'speed_table' needs at least two points")
    return tuple(pts)


def format_speed_table(table) -> str:
    """The text ``"rho:g rho:g ..."`` of a table's points (:func:`parse_speed_table`)."""
    return " ".join(f"{x:g}:{g:g}" for x, g in parse_speed_table(table))


def speed_law_from(params) -> SpeedLaw:
    """The :class:`SpeedLaw` of an object or mapping with ``speed_law``, ``U_f``, ``beta``,
    ``rho_jam``, ``gamma_w``, ``speed_table`` (missing ones: the defaults)."""
    get = params.get if isinstance(params, dict) else (lambda k, d: getattr(params, k, d))
    d = SpeedLaw()
    return SpeedLaw(name=get("speed_law", d.name), U_f=get("U_f", d.U_f),
                    beta=get("beta", d.beta), rho_jam=get("rho_jam", d.rho_jam),
                    gamma_w=get("gamma_w", d.gamma_w), table=get("speed_table", ()))


def cone_norm(p: float) -> float:
    """The normalisation of the density cone of exponent ``p`` > 0: 1 / mean over all
    directions of max(0, cos)^p, so that a uniform crowd reads its density;
    2 sqrt(pi) Gamma(p/2 + 1) / Gamma((p + 1) / 2) (pi for p = 1, 4 for p = 2)."""
    return 2.0 * math.sqrt(math.pi) * math.gamma(0.5 * p + 1.0) / math.gamma(0.5 * (p + 1.0))
