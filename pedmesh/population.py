"""Who the people in a start area are: premovement times, free walking speeds and body
radii drawn from distributions, and the exits they head for (RiMEA guideline 4.1.1).

A start area of a room file may give (all optional)::

    "premovement": {"distribution": "uniform", "min": 10, "max": 100},          # [s]
    "speed": {"distribution": "normal", "mean": 1.34, "sd": 0.26,
              "min": 0.46, "max": 2.22},                                        # [m/s]
    "radius": {"distribution": "uniform", "min": 0.2, "max": 0.25},             # [m]
    "exits": ["north", "east"]            # or {"north": 0.7, "east": 0.3} (fractions)
    "arrivals": {"rate": 2.5, "start": 0}  # or {"times": [0.0, 0.4, ...]}  [1/s], [s]

``arrivals`` makes the area an entrance (:class:`Arrivals`): its people are not in the room
at the start but enter it in the area, one at each arrival time (a regular ``rate`` from
``start``, or the given ``times``), as soon as there is room for them there. It replaces
``premovement`` (a person who arrives walks at once).

A number instead of a distribution is a constant. Distributions (:class:`Distribution`):

* ``constant``: ``value``;
* ``uniform``: ``min``, ``max``;
* ``normal``: ``mean``, ``sd``, optional ``min``/``max`` (truncated there: values outside
  are not drawn, the density is renormalised);
* ``lognormal``: ``mu``, ``sigma`` of ln(x) (median exp(mu); ``mu`` in [-10, 10],
  ``sigma`` up to 5), optional ``min``/``max`` (truncated likewise).

Each quantity has a physical range (:data:`RANGES`), checked against every value the
distribution draws (a constant's ``value``; ``min`` and ``max``, or for an untruncated tail
its :data:`TAIL` quantile): ``speed`` in [0.1, 5] m/s and ``radius`` in [0.05, 1] m, the
ranges of the models' ``U_f`` and ``r`` (:mod:`pedmesh.parameters`) whose values they
replace, and ``premovement`` in [0, 3600] s (:data:`MAX_PREMOVEMENT_S`).

Drawing is reproducible: the run's seed (``seed``, default 0) seeds one generator, and each
start area and quantity draws from its own stream derived from it, so adding a quantity to
one area does not change the draws of another. Without ``speed`` or ``radius`` everyone has
the model's ``U_f`` and ``r``; without ``premovement`` everyone starts at t = 0; without
``exits`` everyone takes the quickest route to any exit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import GeometryError

__all__ = ["Distribution", "distribution_from_spec", "check_range", "RANGES",
           "MAX_PREMOVEMENT_S", "Population", "draw_population", "exit_choice_from_spec",
           "Arrivals", "arrivals_from_spec"]

_KINDS = {
    "constant": ("value",),
    "uniform": ("min", "max"),
    "normal": ("mean", "sd"),
    "lognormal": ("mu", "sigma"),
}
_OPTIONAL = {"constant": (), "uniform": (), "normal": ("min", "max"),
             "lognormal": ("min", "max")}
#: the range of a lognormal's ``mu``: a median exp(mu) from 4.5e-5 to 22,026 in the
#: quantity's unit (s, m/s, m), beyond anything a premovement time, speed or radius takes
#: (exp(mu) overflows from mu = 710 on)
LOGNORMAL_MU = (-10.0, 10.0)
#: the largest lognormal ``sigma``: its 99th percentile is then 1e5 times its median
LOGNORMAL_SIGMA = 5.0
#: [s] the longest premovement time a start area's people may have: an hour, beyond the
#: minutes of evacuation studies' premovement times and far beyond a run's default end
#: (:data:`pedmesh.parameters.DEFAULT_T_END_S`, 1000 s)
MAX_PREMOVEMENT_S = 3600.0
#: the probability of an untruncated tail beyond the quantile :func:`check_range` checks
#: (one person in 10,000 draws a value beyond it)
TAIL = 1e-4


def _ranges() -> dict[str, tuple[float, float, str, str]]:
    from .parameters import get

    u, r = get("U_f"), get("r")
    return {
        "speed": (*u.range, u.unit, "the range of the models' free speed U_f, which it "
                                    "replaces"),
        "radius": (*r.range, r.unit, "the range of the models' body radius r, which it "
                                     "replaces"),
        "premovement": (0.0, MAX_PREMOVEMENT_S, "s", "at most an hour"),
    }


#: the physical range of each quantity a start area's people draw: name -> (low, high,
#: unit, why); closed intervals
RANGES = _ranges()


@dataclass(frozen=True)
class Distribution:
    """A distribution of a non-negative quantity (see the module docstring)."""

    kind: str
    value: float | None = None
    min: float | None = None
    max: float | None = None
    mean: float | None = None
    sd: float | None = None
    mu: float | None = None
    sigma: float | None = None

    def _frozen(self):
        """The scipy.stats distribution (truncated where bounds are given)."""
        from scipy import stats

        if self.kind == "uniform":
            return stats.uniform(loc=self.min, scale=self.max - self.min)
        lo = -math.inf if self.min is None else self.min
        hi = math.inf if self.max is None else self.max
        if self.kind == "normal":
            a, b = (lo - self.mean) / self.sd, (hi - self.mean) / self.sd
            return stats.truncnorm(a, b, loc=self.mean, scale=self.sd)
        base = stats.lognorm(s=self.sigma, scale=math.exp(self.mu))
        if self.min is None and self.max is None:
            return base
        return _Truncated(base, max(lo, 0.0), hi)

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` values drawn with ``rng``."""
        if self.kind == "constant":
            return np.full(n, float(self.value))
        if n == 0:
            return np.zeros(0)
        return np.asarray(self._frozen().ppf(rng.uniform(size=n)), float)

    def cdf(self, x) -> np.ndarray:
        """P(X <= x)."""
        x = np.asarray(x, float)
        if self.kind == "constant":
            return (x >= self.value).astype(float)
        return np.asarray(self._frozen().cdf(x), float)

    def to_spec(self) -> float | dict[str, Any]:
        """The room-file form (inverse of :func:`distribution_from_spec`)."""
        if self.kind == "constant":
            return self.value
        out: dict[str, Any] = {"distribution": self.kind}
        for k in (*_KINDS[self.kind], *_OPTIONAL[self.kind]):
            if getattr(self, k) is not None:
                out[k] = getattr(self, k)
        return out

    @property
    def mean_value(self) -> float:
        if self.kind == "constant":
            return float(self.value)
        return float(self._frozen().mean())

    @property
    def upper(self) -> float:
        """The largest value it can take (inf if unbounded)."""
        if self.kind == "constant":
            return float(self.value)
        return float(self._frozen().ppf(1.0))


class _Truncated:
    """A scipy frozen distribution truncated to [lo, hi] (cdf, ppf, mean)."""

    def __init__(self, base, lo: float, hi: float) -> None:
        self.base, self.lo, self.hi = base, lo, hi
        self.F0, self.F1 = float(base.cdf(lo)), float(base.cdf(hi))

    def cdf(self, x):
        x = np.clip(x, self.lo, self.hi)
        return (self.base.cdf(x) - self.F0) / (self.F1 - self.F0)

    def ppf(self, q):
        return self.base.ppf(self.F0 + np.asarray(q) * (self.F1 - self.F0))

    def mean(self):
        from scipy.integrate import quad

        return quad(lambda t: t * self.base.pdf(t), self.lo, self.hi)[0] / (self.F1 - self.F0)


def distribution_from_spec(spec: Any, what: str, where: str, *,
                           positive: bool = False) -> Distribution:
    """A :class:`Distribution` from a room file's value (a number or a dict), with one-line
    errors naming ``where`` (e.g. "start area 'hall'") and the quantity ``what``."""
    label = f"{where}: '{what}'"

    def number(v, name):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise GeometryError(f"{label}: '{name}' must be a finite number, got {v!r}")
        return float(v)

    if isinstance(spec, (int, float)) and not isinstance(spec, bool):
        spec = {"distribution": "constant", "value": spec}
    if not isinstance(spec, dict):
        raise GeometryError(f"{label} must be a number or an object like "
                            f"{{\"distribution\": \"uniform\", \"min\": 0, \"max\": 60}}, "
                            f"got {spec!r}")
    kind = spec.get("distribution")
    if kind not in _KINDS:
        raise GeometryError(f"{label}: unknown distribution {kind!r} (distributions: "
                            f"{', '.join(_KINDS)})")
    need, opt = _KINDS[kind], _OPTIONAL[kind]
    bad = sorted(set(spec) - {"distribution", *need, *opt})
    if bad:
        raise GeometryError(f"{label}: unknown key '{bad[0]}' for a {kind} distribution "
                            f"(keys: {', '.join((*need, *opt))})")
    missing = [k for k in need if k not in spec]
    if missing:
        raise GeometryError(f"{label}: a {kind} distribution needs '{missing[0]}'")
    vals = {k: number(spec[k], k) for k in (*need, *opt) if k in spec}
    d = Distribution(kind, **vals)
    lo = {"constant": d.value, "uniform": d.min}.get(kind, d.min)
    if kind == "uniform" and not d.max > d.min:
        raise GeometryError(f"{label}: 'max' must exceed 'min' (got {d.min:g}, {d.max:g})")
    if kind in ("normal", "lognormal"):
        s = d.sd if kind == "normal" else d.sigma
        if not s > 0:
            raise GeometryError(f"{label}: '{'sd' if kind == 'normal' else 'sigma'}' must be "
                                f"positive, got {s:g}")
        if kind == "lognormal":
            lo_mu, hi_mu = LOGNORMAL_MU
            if not lo_mu <= d.mu <= hi_mu:
                raise GeometryError(
                    f"{label}: 'mu' must be in [{lo_mu:g}, {hi_mu:g}] (a median exp(mu) from "
                    f"{math.exp(lo_mu):.2g} to {math.exp(hi_mu):.5g}), got {d.mu:g}")
            if d.sigma > LOGNORMAL_SIGMA:
                raise GeometryError(f"{label}: 'sigma' must be in (0, {LOGNORMAL_SIGMA:g}], "
                                    f"got {d.sigma:g}")
        if d.min is not None and d.max is not None and not d.max > d.min:
            raise GeometryError(f"{label}: 'max' must exceed 'min' (got {d.min:g}, {d.max:g})")
        if kind == "normal" and d.min is None:
            raise GeometryError(f"{label}: a normal distribution of a {what} needs a 'min' "
                                f"(it must not draw negative values)")
        if kind == "lognormal" and d.min is not None and d.min < 0:
            raise GeometryError(f"{label}: 'min' must be >= 0, got {d.min:g}")
    if lo is not None and (lo < 0 or (positive and lo <= 0)):
        raise GeometryError(f"{label}: values must be {'positive' if positive else '>= 0'}, "
                            f"got a lower end of {lo:g}")
    if kind == "normal" and d.max is not None and d.max <= d.min:
        raise GeometryError(f"{label}: 'max' must exceed 'min'")
    if kind in ("normal", "lognormal") and (d.min is not None or d.max is not None):
        # (a truncation window where the distribution has next to no mass: a mistake)
        from scipy import stats

        base = (stats.norm(d.mean, d.sd) if kind == "normal"
                else stats.lognorm(s=d.sigma, scale=math.exp(d.mu)))
        lo = -math.inf if d.min is None else d.min
        hi = math.inf if d.max is None else d.max
        mass = float(base.cdf(hi) - base.cdf(lo))
        if not mass > 1e-6:
            raise GeometryError(f"{label}: the distribution has no mass between 'min' and "
                                f"'max' (probability {mass:.1e})")
    return d


def check_range(d: Distribution, what: str, where: str) -> Distribution:
    """``d`` if every value it draws lies in the physical range of ``what`` (:data:`RANGES`;
    other quantities are not checked): a constant's value, ``min`` and ``max``, and for an
    untruncated tail its :data:`TAIL` quantile. Else a one-line error naming ``where``
    (e.g. "start area 'hall'"), the quantity, the range and the value."""
    if what not in RANGES:
        return d
    lo, hi, unit, why = RANGES[what]
    if d.kind == "constant":
        ends = [(d.value, f"{d.value:g}")]
    else:
        ends = []
        for name, q in (("min", TAIL), ("max", 1.0 - TAIL)):
            v = getattr(d, name)
            if v is not None:
                ends.append((v, f"'{name}' {v:g}"))
            else:
                v = float(d._frozen().ppf(q))
                ends.append((v, f"{v:.3g} at its {100 * q:g} % quantile (give '{name}' to "
                                f"truncate it)"))
    for v, shown in ends:
        if not lo <= v <= hi:
            raise GeometryError(f"{where}: '{what}': values must be in [{lo:g}, {hi:g}] "
                                f"{unit} ({why}), got {shown}")
    return d


class Arrivals:
    """When the people of an entrance (a start area with ``arrivals``) enter the room.

    ``times`` (count,) arrival times [s], ascending; ``rate`` [1/s] and ``start`` [s] when
    they were given as a regular rate (``times = start + k / rate`` for k < ``count``),
    else None. A regular schedule makes its times when they are first asked for: reading a
    room file allocates nothing per person, so that a run checks the crowd's size
    (:func:`pedmesh.run.driver.check_crowd`) before memory for a huge ``count`` is taken.
    Immutable, like the start area that holds it.
    """

    def __init__(self, times: Any = None, rate: float | None = None,
                 start: float | None = None, count: int | None = None) -> None:
        if times is None:
            if rate is None or count is None:
                raise TypeError("Arrivals needs 'times', or 'rate' and 'count'")
            given, n = None, int(count)
            start = 0.0 if start is None else start
        else:
            given = tuple(float(t) for t in times)
            n = len(given)
        for key, value in (("rate", rate), ("start", start), ("count", n), ("_times", given)):
            object.__setattr__(self, key, value)

    def __setattr__(self, key: str, value: Any) -> None:
        raise AttributeError(f"Arrivals is immutable (cannot set '{key}')")

    @property
    def times(self) -> tuple[float, ...]:
        if self._times is None:  # (a regular schedule, made once)
            object.__setattr__(self, "_times", tuple(float(self.start + k / self.rate)
                                                     for k in range(self.count)))
        return self._times

    def _key(self) -> tuple:
        return (self.rate, self.start, self.count,
                self.times if self.rate is None else None)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Arrivals):
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def __repr__(self) -> str:
        if self.rate is not None:
            return f"Arrivals(rate={self.rate!r}, start={self.start!r}, count={self.count})"
        return f"Arrivals(times={self.times!r}, rate={self.rate!r}, start={self.start!r})"

    def cdf(self, t) -> np.ndarray:
        """The fraction of the people who have arrived by time ``t`` [s] (the schedule's
        empirical distribution; the continuum models add people by it)."""
        tt = np.asarray(self.times, float)
        return np.searchsorted(tt, np.asarray(t, float), side="right") / max(len(tt), 1)

    def to_spec(self) -> dict[str, Any]:
        """The room-file form (inverse of :func:`arrivals_from_spec`)."""
        if self.rate is not None:
            return {"rate": self.rate, "start": self.start}
        return {"times": list(self.times)}


def arrivals_from_spec(spec: Any, count: int | None, where: str) -> Arrivals:
    """:class:`Arrivals` from a room file's ``arrivals`` value: ``{"rate": r [1/s], "start":
    t0 [s] (default 0)}`` for ``count`` people, or ``{"times": [t, ...] [s]}`` (ascending,
    >= 0; their number must equal ``count`` if that is given). One-line errors name
    ``where``."""
    if isinstance(spec, Arrivals):
        spec = spec.to_spec()
    label = f"{where}: 'arrivals'"
    if not isinstance(spec, dict) or not (("rate" in spec) ^ ("times" in spec)):
        raise GeometryError(f"{label} must be an object with either 'rate' [1/s] (and "
                            f"optionally 'start' [s]) or 'times' [s], got {spec!r}")
    allowed = {"rate", "start"} if "rate" in spec else {"times"}
    bad = sorted(set(spec) - allowed)
    if bad:
        raise GeometryError(f"{label}: unknown key '{bad[0]}' (keys: {', '.join(sorted(allowed))})")

    def number(v, name):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise GeometryError(f"{label}: '{name}' must be a finite number, got {v!r}")
        return float(v)

    if "rate" in spec:
        rate = number(spec["rate"], "rate")
        start = number(spec.get("start", 0.0), "start")
        if rate <= 0:
            raise GeometryError(f"{label}: 'rate' must be positive, got {rate:g}")
        if start < 0:
            raise GeometryError(f"{label}: 'start' must be >= 0, got {start:g}")
        if count is None:
            raise GeometryError(f"{label}: a 'rate' needs the area's 'count'")
        return Arrivals(rate=rate, start=start, count=count)  # (its times: when asked for)
    times = spec["times"]
    if not isinstance(times, (list, tuple)) or not times:
        raise GeometryError(f"{label}: 'times' must be a non-empty list of times [s]")
    tt = [number(v, "times") for v in times]
    if min(tt) < 0:
        raise GeometryError(f"{label}: 'times' must be >= 0, got {min(tt):g}")
    if any(b < a for a, b in zip(tt, tt[1:])):
        raise GeometryError(f"{label}: 'times' must be in ascending order")
    if count is not None and count != len(tt):
        raise GeometryError(f"{label}: {len(tt)} times for a 'count' of {count}")
    return Arrivals(tuple(tt))


def exit_choice_from_spec(spec: Any, where: str) -> tuple[tuple[str, float | None], ...]:
    """``((exit name, fraction), ...)`` from a start area's ``exits``: an object gives each
    exit's fraction of the area's people (adding up to 1); a list of names means 'any of
    these, by the quickest route' (fractions None). Already in that form: checked again."""
    if isinstance(spec, tuple):
        if all(f is None for _, f in spec):
            spec = [n for n, _ in spec]
        else:
            spec = dict(spec)
    if isinstance(spec, list):
        if not spec or not all(isinstance(s, str) for s in spec):
            raise GeometryError(f"{where}: 'exits' must be a non-empty list of exit names or "
                                f"an object {{name: fraction}}, got {spec!r}")
        if len(set(spec)) != len(spec):
            raise GeometryError(f"{where}: 'exits' names an exit twice")
        return tuple((s, None) for s in spec)
    if isinstance(spec, dict) and spec:
        out = {}
        for k, v in spec.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (
                    math.isfinite(v) and v >= 0):
                raise GeometryError(f"{where}: the fraction of exit '{k}' must be a number "
                                    f">= 0, got {v!r}")
            out[str(k)] = float(v)
        total = sum(out.values())
        if not abs(total - 1.0) <= 1e-6:
            raise GeometryError(f"{where}: the exit fractions must add up to 1, got {total:g}")
        return tuple(out.items())
    raise GeometryError(f"{where}: 'exits' must be a non-empty list of exit names or an "
                        f"object {{name: fraction}}, got {spec!r}")


@dataclass
class Population:
    """Per-pedestrian attributes of a run, in the order of ``room.initial_positions()``.

    ``area`` (N,) start-area index; ``premovement`` (N,) [s]; ``speed`` (N,) free speed
    [m/s] (NaN: the model's U_f); ``radius`` (N,) [m] (NaN: the model's r); ``target`` (N,)
    index into ``targets``, the distinct exit sets (tuples of exit names; the empty tuple:
    any exit); ``arrival`` (N,) [s] when each enters the room (NaN: in it from the start;
    entrances, start areas with ``arrivals``)."""

    area: np.ndarray
    premovement: np.ndarray
    speed: np.ndarray
    radius: np.ndarray
    target: np.ndarray
    targets: list[tuple[str, ...]]
    arrival: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.arrival is None:
            self.arrival = np.full(len(self.premovement), np.nan)

    @property
    def has_arrivals(self) -> bool:
        return bool(np.any(np.isfinite(self.arrival)))

    @property
    def has_premovement(self) -> bool:
        return bool(np.any(self.premovement > 0))

    @property
    def has_targets(self) -> bool:
        return any(len(t) for t in self.targets)


def draw_population(room, counts: list[int] | None = None, seed: int = 0) -> Population:
    """Draw every start area's attributes (``counts``: pedestrians per area, default those
    of ``room.initial_positions()``), reproducibly with ``seed``."""
    areas = room.start_areas
    if counts is None:
        counts = [len(a.positions(room.walkable)) for a in areas]
    n = int(sum(counts))
    area = np.repeat(np.arange(len(areas)), counts)
    pre = np.zeros(n)
    speed = np.full(n, np.nan)
    radius = np.full(n, np.nan)
    target = np.zeros(n, np.int64)
    arrival = np.full(n, np.nan)
    targets: list[tuple[str, ...]] = [()]
    root = np.random.SeedSequence(int(seed))
    streams = root.spawn(max(len(areas), 1))
    start = 0
    for k, (a, c) in enumerate(zip(areas, counts)):
        sl = slice(start, start + c)
        start += c
        rng_pre, rng_speed, rng_rad, rng_exit = (np.random.default_rng(s)
                                                 for s in streams[k].spawn(4))
        if getattr(a, "arrivals", None) is not None:
            arrival[sl] = np.resize(np.asarray(a.arrivals.times, float), c)
        if a.premovement is not None:
            pre[sl] = a.premovement.sample(rng_pre, c)
        if a.speed is not None:
            speed[sl] = a.speed.sample(rng_speed, c)
        if a.radius is not None:
            radius[sl] = a.radius.sample(rng_rad, c)
        if a.exits is not None:
            names = [e for e, _ in a.exits]
            if all(f is None for _, f in a.exits):  # any of these, by the quickest route
                key = tuple(sorted(names))
                if key not in targets:
                    targets.append(key)
                target[sl] = targets.index(key)
            else:  # exactly round(fraction * c) to each, in random order
                quota = _quotas(np.array([f for _, f in a.exits]), c)
                pick = np.repeat(np.arange(len(names)), quota)
                rng_exit.shuffle(pick)
                for e, name in enumerate(names):
                    key = (name,)
                    if key not in targets:
                        targets.append(key)
                    target[sl][pick == e] = targets.index(key)
    return Population(area, pre, speed, radius, target, targets, arrival)


def _quotas(frac: np.ndarray, n: int) -> np.ndarray:
    """Whole numbers adding up to ``n`` as close as can be to ``frac * n`` (largest
    remainders)."""
    raw = frac * n
    q = np.floor(raw).astype(np.int64)
    rest = n - int(q.sum())
    if rest > 0:
        q[np.argsort(-(raw - q), kind="stable")[:rest]] += 1
    return q
