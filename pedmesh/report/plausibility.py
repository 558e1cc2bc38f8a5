"""The plausibility panel's checks: a run's exit flows, densities and speeds against what
real crowds were measured to do, and the parameter preset named with what it was fitted to.

* **Exit flow.** Per exit, the largest mean flow over :data:`FLOW_WINDOW_S` (10 s) of
  ``outflow.csv`` divided by the exit's width (its length along the wall): the specific
  flow [people/(m·s)]. Against the specific flows J/b of every published bottleneck
  experiment pedmesh holds (``pedmesh/data/bottleneck_literature.json``,
  :func:`pedmesh.validation.published_bottleneck_flows`: seven series, openings 0.4-5.0 m
  wide, 1.61-2.74 people/(m·s)). Flagged above the highest by more than
  :data:`FLOW_TOLERANCE` (10 %, the tolerance pedmesh's own validation passes a flow with:
  ``docs/validation/fit.md``); between the highest and that, "at the edge". Below the
  lowest is not flagged: an exit without a queue in front of it never runs at capacity.
* **Peak density.** The run's peak density (the crowd-safety measure on 1 m² where the run
  has it, else the densest mesh cell of the saved frames) against the densest crowds
  measured: 6-9 /m² in front of entrances (Adrian, Seyfried & Sieben 2020; close packing
  at about 9 /m², Nicolas et al. 2017; :data:`pedmesh.validation.
  PRESSING_FRONT_DENSITY_PER_M2`). Flagged above 9 /m².
* **Speed at density.** The people-weighted mean speed of the crowd in bands of density
  (:data:`SPEED_BANDS`, every saved frame after the first, the cells' density and velocity
  of ``density.pvd``) against Weidmann's fundamental diagram
  (:func:`pedmesh.validation.weidmann_speed`, weighted the same way), give or take
  :func:`speed_tolerance`: the spread of single walkers' free speeds (0.26 m/s, Weidmann
  1993) plus the most that the Jülich corridor experiments walked faster than the diagram
  (0.23 m/s at 1.64 /m², :data:`pedmesh.validation.EXPERIMENT_TABLE`), 0.49 m/s. Flagged
  where the crowd is faster than that; slower is said, not flagged (a slower crowd makes
  the evacuation longer, not shorter). A band with under :data:`MIN_SHARE` of the
  people-time is not judged.

The checks (:func:`exit_flow_check`, :func:`peak_density_check`, :func:`speed_bands`,
:func:`speed_check`, :func:`preset_sentence`) are pure functions of numbers;
:func:`run_checks` applies them to a run folder.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field
from functools import cache
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from ..validation import (EXPERIMENT_TABLE, FREE_SPEED_SD_MS, PRESSING_FRONT_DENSITY_PER_M2,
                          REFERENCE_NOTES, published_bottleneck_flows, weidmann_speed)
from .load import Run
from .measures import moving_mean
from .text import is_num, number

__all__ = ["Check", "Panel", "FLOW_WINDOW_S", "FLOW_TOLERANCE", "SPEED_BANDS", "MIN_SHARE",
           "bottleneck_band", "speed_tolerance", "exit_flow_check", "peak_density_check",
           "SpeedBand", "speed_bands", "speed_check", "preset_sentence", "run_checks",
           "summary_sentence", "method_sentences"]

#: [s] the window of the exit flow's mean (the stair table's peak flow is over 10 s too)
FLOW_WINDOW_S = 10.0
#: how far above the highest published specific flow a run's may be before it is flagged:
#: the tolerance pedmesh's validation passes a flow with (docs/validation/fit.md)
FLOW_TOLERANCE = 0.10
#: [/m²] the edges of the density bands of the speed check (the last band open above)
SPEED_BANDS = (0.5, 1.5, 2.5, 3.5, 4.5, 5.5)
#: a band with less than this share of the crowd's people-time is not judged
MIN_SHARE = 0.02
#: the presets fitted to measurements of real crowds (pedmesh.presets: 'paper' is the
#: paper's Table 1, 'weidmann' literature values, not fitted)
FITTED_PRESETS = ("validated",)

#: the verdicts: within the published range; outside it but within the tolerance; below it
#: (not flagged: a longer evacuation, not a shorter one); outside (flagged); not judged
VERDICTS = ("within", "edge", "below", "outside", "unknown")


@dataclass(frozen=True)
class Check:
    """One line of the panel: what is checked, the run's value (with its unit), the
    published range in words, the verdict (one of :data:`VERDICTS`) and what it means."""

    measure: str
    value: float | None
    unit: str
    reference: str
    verdict: str
    comment: str = ""

    @property
    def flagged(self) -> bool:
        return self.verdict == "outside"


@dataclass
class Panel:
    """A run's plausibility: the sentence on its preset and the checks."""

    preset: str
    checks: list[Check] = field(default_factory=list)

    @property
    def flagged(self) -> list[Check]:
        return [c for c in self.checks if c.flagged]

    @property
    def at_edge(self) -> list[Check]:
        return [c for c in self.checks if c.verdict == "edge"]


# ------------------------------------------------------------------ published ranges
@cache
def bottleneck_band() -> tuple[float, float, int, float, float]:
    """(lowest, highest) specific flow J/b [people/(m·s)] of the published bottleneck
    experiments (every point of :func:`pedmesh.validation.published_bottleneck_flows`), how
    many points, and the narrowest and widest opening [m]."""
    series = published_bottleneck_flows()
    jb = np.concatenate([s["points"][:, 1] / s["points"][:, 0] for s in series])
    widths = np.concatenate([s["points"][:, 0] for s in series])
    return float(jb.min()), float(jb.max()), len(jb), float(widths.min()), float(widths.max())


@cache
def speed_tolerance() -> tuple[float, float, float]:
    """(tolerance, walkers' spread, Jülich excess) [m/s]: the spread of single walkers'
    free speeds (Weidmann 1993) plus the most the Jülich corridor experiments walked faster
    than Weidmann's diagram at their density (the values the measurement reproduces)."""
    excess = max(r["speed"] - float(weidmann_speed(r["density"]))
                 for name, r in EXPERIMENT_TABLE.items() if (name, "speed") not in REFERENCE_NOTES)
    return FREE_SPEED_SD_MS + excess, FREE_SPEED_SD_MS, excess


# ------------------------------------------------------------------ the checks
def exit_flow_check(name: str, width: float | None, t: np.ndarray,
                    flow: np.ndarray) -> Check:
    """The check of exit ``name``, ``width`` [m] wide (None: unknown), whose flow [people/s]
    at times ``t`` [s] is ``flow`` (``outflow.csv``'s column: the mean since the row
    before)."""
    lo, hi, n, b0, b1 = bottleneck_band()
    limit = hi * (1.0 + FLOW_TOLERANCE)
    measure = f"peak flow per metre of width, exit '{name}'" + (
        f" ({number(width, 3)} m wide)" if is_num(width) and width > 0 else "")
    ref = (f"{lo:.2f}-{hi:.2f} people/(m·s) in {n} bottleneck experiments, openings "
           f"{b0:g}-{b1:g} m wide")
    t = np.asarray(t, float)
    flow = np.asarray(flow, float)
    if not width or not width > 0:
        return Check(measure, None, "people/(m·s)", ref, "unknown",
                     "the exit's width is not known (the room file was not found)")
    if len(t) < 2 or not np.any(flow > 0):
        return Check(measure, None, "people/(m·s)", ref, "unknown",
                     "nobody left through this exit")
    mean = moving_mean(t, flow, FLOW_WINDOW_S)
    k = int(np.argmax(mean))
    jb = float(mean[k]) / width
    when = f"the largest mean over {FLOW_WINDOW_S:g} s, at t = {t[k]:.0f} s, per metre of width"
    if jb > limit:
        return Check(measure, jb, "people/(m·s)", ref, "outside",
                     f"{when}: {100 * (jb / hi - 1):.0f} % above the highest experiment. "
                     "More people pass this exit than real crowds pass an opening of this "
                     "width, so the evacuation times are likely too short")
    if jb > hi:
        return Check(measure, jb, "people/(m·s)", ref, "edge",
                     f"{when}: {100 * (jb / hi - 1):.0f} % above the highest experiment, "
                     f"within the {100 * FLOW_TOLERANCE:.0f} % tolerance")
    if jb < lo:
        return Check(measure, jb, "people/(m·s)", ref, "below",
                     f"{when}: below the experiments, as at an exit that never had a queue "
                     "in front of it (not flagged: it makes the evacuation longer, if "
                     "anything)")
    return Check(measure, jb, "people/(m·s)", ref, "within", when)


def peak_density_check(value: float | None, *, over: str = "") -> Check:
    """The check of the run's peak density ``value`` [/m²], measured ``over`` (words)."""
    front, packed = PRESSING_FRONT_DENSITY_PER_M2
    measure = "peak density" + (f" ({over})" if over else "")
    ref = (f"at most about {packed:g} /m² (close packing); {front:g}-{packed:g} /m² in front "
           "of entrances where crowds press")
    if not is_num(value):
        return Check(measure, None, "/m²", ref, "unknown", "no density recorded")
    value = float(value)
    if value > packed:
        return Check(measure, value, "/m²", ref, "outside",
                     "denser than people can stand: the model packs its crowd tighter than "
                     "any measured crowd")
    if value >= front:
        return Check(measure, value, "/m²", ref, "within",
                     "as dense as crowds pressing at an entrance: dangerous, but measured")
    return Check(measure, value, "/m²", ref, "within")


@dataclass(frozen=True)
class SpeedBand:
    """A density band [/m²] (``hi`` inf: open above), its share of the crowd's
    people-time, the crowd's mean speed there and Weidmann's [m/s], weighted alike."""

    lo: float
    hi: float
    share: float
    speed: float
    weidmann: float


def speed_bands(samples: Iterable[tuple[np.ndarray, np.ndarray, np.ndarray]],
                edges: Sequence[float] = SPEED_BANDS) -> list[SpeedBand]:
    """The bands of ``samples`` (density [/m²], speed [m/s], area [m²] of each cell of a
    frame), each cell weighted by its people (density times area); bands without people
    are left out."""
    bounds = np.append(np.asarray(edges, float), np.inf)
    m = len(bounds) - 1
    people, speed, weid = np.zeros(m), np.zeros(m), np.zeros(m)
    for rho, v, area in samples:
        rho, v, area = (np.asarray(a, float) for a in (rho, v, area))
        k = np.searchsorted(bounds, rho, side="right") - 1
        ok = (k >= 0) & (k < m) & np.isfinite(v)
        w = rho[ok] * area[ok]
        np.add.at(people, k[ok], w)
        np.add.at(speed, k[ok], w * v[ok])
        np.add.at(weid, k[ok], w * np.asarray(weidmann_speed(rho[ok]), float))
    total = people.sum()
    return [SpeedBand(float(bounds[i]), float(bounds[i + 1]), float(people[i] / total),
                      float(speed[i] / people[i]), float(weid[i] / people[i]))
            for i in range(m) if people[i] > 0]


def speed_check(band: SpeedBand) -> Check:
    """The check of one density band against Weidmann's diagram."""
    tol = speed_tolerance()[0]
    where = (f"{band.lo:g}-{band.hi:g} /m²" if math.isfinite(band.hi)
             else f"{band.lo:g} /m² and more")
    measure = f"walking speed at {where}"
    ref = f"{band.weidmann:.2f} m/s (Weidmann), give or take {tol:.2f} m/s"
    diff = band.speed - band.weidmann
    share = f"{100 * band.share:.0f} % of the crowd's time"
    if band.share < MIN_SHARE:
        return Check(measure, band.speed, "m/s", ref, "unknown",
                     f"too few people at these densities ({share})")
    if diff > tol:
        return Check(measure, band.speed, "m/s", ref, "outside",
                     f"{diff:.2f} m/s faster than measured crowds at these densities "
                     f"({share})")
    if diff < -tol:
        return Check(measure, band.speed, "m/s", ref, "below",
                     f"{-diff:.2f} m/s slower than Weidmann's diagram ({share}; not flagged: "
                     "it makes the evacuation longer, if anything)")
    return Check(measure, band.speed, "m/s", ref, "within", f"{diff:+.2f} m/s ({share})")


def preset_sentence(settings: Mapping[str, Any]) -> str:
    """The run's parameter preset in words, with what it was fitted to and any parameter
    the run changed (``settings``: summary.json's "settings")."""
    from ..presets import PRESETS

    name = settings.get("preset")
    if not name:
        return ("The run does not record its parameter preset (it was made before pedmesh "
                "recorded presets).")
    preset = PRESETS.get(name)
    text = (f"Parameter preset '{name}': {preset.description}." if preset is not None
            else f"Parameter preset '{name}' (not one this pedmesh knows).")
    if name not in FITTED_PRESETS:
        text += (" It was not fitted to measurements of real crowds; of pedmesh's presets, "
                 + " and ".join(f"'{p}'" for p in FITTED_PRESETS) + " was.")
    changed = settings.get("overrides") or {}
    if changed:
        one = len(changed) == 1
        text += (f" The run sets {len(changed)} parameter{'' if one else 's'} itself ("
                 + ", ".join(f"{k} = {v}" for k, v in changed.items())
                 + f"): the preset's fit does not cover {'it' if one else 'them'}.")
    return text


def _no_speeds(why: str) -> Check:
    return Check("walking speed at density", None, "m/s", "Weidmann's diagram", "unknown",
                 why)


# ------------------------------------------------------------------ a run's checks
_PANELS: "weakref.WeakKeyDictionary[Run, Panel]" = weakref.WeakKeyDictionary()


def run_checks(run: Run) -> Panel:
    """The plausibility of ``run`` (computed once per run)."""
    if run in _PANELS:
        return _PANELS[run]
    panel = Panel(preset_sentence(run.result.settings or {}))
    t, flows, names = run.outflow
    widths = run.exit_widths
    for k, name in enumerate(names):
        panel.checks.append(exit_flow_check(name, widths.get(name), t, flows[:, k]))
    pk = (run.safety or {}).get("peak_density") or {}
    if is_num(pk.get("value")):
        panel.checks.append(peak_density_check(pk["value"], over="averaged over 1 m²"))
    elif run.frames is not None:
        panel.checks.append(peak_density_check(float(run.frames.peak[0].max()),
                                               over="densest mesh cell of the saved frames"))
    else:
        panel.checks.append(peak_density_check(None))
    fr = run.frames
    if fr is not None:
        def samples():
            for k in range(1, len(fr.times)):  # (the first frame: the crowd at rest)
                rho, speed = fr.fields(k)
                if speed is not None:
                    yield rho, speed, fr.areas

        bands = speed_bands(samples())
        panel.checks += [speed_check(b) for b in bands] or [_no_speeds(
            "the saved frames hold no velocities")]
    else:
        panel.checks.append(_no_speeds("no density frames were saved"))
    _PANELS[run] = panel
    return panel


def summary_sentence(panel: Panel) -> str:
    """The panel in one sentence for the page's summary."""
    def listed(checks: list[Check]) -> str:
        return "; ".join(f"{c.measure}: {c.value:.2f} {c.unit}" for c in checks)

    bad = panel.flagged
    if bad:
        return (f"Plausibility: outside what real crowds were measured to do: {listed(bad)} "
                "(see the plausibility check).")
    edge = panel.at_edge
    if edge:
        return (f"Plausibility: nothing flagged, but at the edge of what real crowds were "
                f"measured to do: {listed(edge)} (within the tolerance; see the plausibility "
                "check).")
    return ("Plausibility: the exit flows, the peak density and the walking speeds are "
            "within what real crowds were measured to do (see the plausibility check).")


def method_sentences() -> list[str]:
    """How the panel checks a run, in plain words with the sources."""
    lo, hi, n, b0, b1 = bottleneck_band()
    tol, spread, excess = speed_tolerance()
    front, packed = PRESSING_FRONT_DENSITY_PER_M2
    series = ", ".join(dict.fromkeys(s["label"] for s in published_bottleneck_flows()))
    return [
        f"Exit flow: the most people per second through each exit, averaged over "
        f"{FLOW_WINDOW_S:g} s, per metre of the exit's width, against the flows measured "
        f"through bottlenecks and doors {b0:g}-{b1:g} m wide ({series}): "
        f"{lo:.2f}-{hi:.2f} people/(m·s). Flagged more than {100 * FLOW_TOLERANCE:.0f} % "
        "above the highest.",
        f"Peak density: flagged above {packed:g} /m², about the densest people can stand; "
        f"crowds pressing at entrances were measured at {front:g}-{packed:g} /m² (Adrian, "
        "Seyfried & Sieben 2020; Nicolas, Bouzat & Kuperman 2017).",
        "Walking speed: the crowd's mean speed in each band of density over the run (every "
        "saved frame but the first, weighted by the people in each mesh cell) against "
        f"Weidmann's fundamental diagram (Weidmann 1993), give or take {tol:.2f} m/s: the "
        f"spread of single walkers' speeds ({spread:.2f} m/s) plus the {excess:.2f} m/s by "
        "which the Jülich corridor experiments walked faster than the diagram. Flagged where "
        "faster.",
        "Lower flows and speeds are not flagged: they make the evacuation longer, not "
        "shorter. A flag says the run is outside what was measured, not that it is wrong; "
        "it asks for a look at the preset and the parameters.",
    ]
