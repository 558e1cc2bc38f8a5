"""What the report computes from a run: the levels of service of densities, the mean of a
flow over a window, and the plain-language summary of a run."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from ..analysis.safety import FRUIN_SCALES, level_of_service
from .load import Run
from .text import is_num, number, people, seconds, unit_text

__all__ = ["FRUIN_LEVELS", "LOS", "moving_mean", "los_index", "los_scale", "describe_place",
           "run_sentences"]

#: Fruin's levels of service A-F by density [ped/m^2]: the upper densities of A, B, C, D
#: and E (F above), walkway and queuing, from the one definition of the tables in
#: :mod:`pedmesh.analysis.safety` (Fruin 1971, in ft^2 per person)
FRUIN_LEVELS: dict[str, tuple[float, ...]] = {
    name: tuple(lv.max_density for lv in levels[:-1]) for name, levels in FRUIN_SCALES.items()}
#: the levels' letters, best first
LOS = "ABCDEF"


def moving_mean(t: np.ndarray, flow: np.ndarray, window: float = 2.0) -> np.ndarray:
    """The mean of a flow sampled at ``t`` over the ``window`` [s] centred on each sample
    (the flow of row k covers (t[k-1], t[k]]): the cumulative count differenced."""
    if len(t) < 2:
        return flow
    dt = np.diff(t, prepend=t[0])
    cum = np.cumsum(flow * dt)
    lo = np.interp(t - 0.5 * window, t, cum, left=0.0)
    hi = np.interp(t + 0.5 * window, t, cum)
    span = np.minimum(t + 0.5 * window, t[-1]) - np.maximum(t - 0.5 * window, t[0])
    return np.where(span > 0, (hi - lo) / np.where(span > 0, span, 1.0), 0.0)


def los_index(rho: np.ndarray, scale: str = "walkway") -> np.ndarray:
    """Fruin's level of service (0 = A ... 5 = F) of densities ``rho`` [ped/m^2]
    (:func:`pedmesh.analysis.safety.level_of_service`)."""
    return level_of_service(density=np.asarray(rho, float),
                            scale=scale if scale in FRUIN_SCALES else "walkway")


def los_scale(safety: Mapping | None) -> str:
    los = (safety or {}).get("level_of_service") or {}
    scale = str(los.get("scale") or "walkway").lower()  # (e.g. "Fruin walkway")
    return "queuing" if "queu" in scale else "walkway"


def describe_place(room, x: Any, y: Any) -> str:
    """Where (x, y) [m] is, in words: by an exit, in a measurement or start area, or the
    coordinates."""
    if not (is_num(x) and is_num(y)):
        return ""
    at = f"at x = {float(x):.1f} m, y = {float(y):.1f} m"
    if room is None:
        return at
    try:
        from shapely.geometry import Point

        pt = Point(float(x), float(y))
        best = min(((e.shape.distance(pt), e.name) for e in room.exits), default=None)
        if best is not None and best[0] <= 3.0:
            return f"in front of exit '{best[1]}' ({at})"
        for a in room.measurement_areas:
            if a.shape.covers(pt):
                return f"in measurement area '{a.name}' ({at})"
        if best is not None and best[0] <= 8.0:
            return f"{best[0]:.0f} m from exit '{best[1]}' ({at})"
    except Exception:
        return at
    return at


def run_sentences(run: Run) -> list[str]:
    """The plain-language summary of one run."""
    s = run.s
    n0 = s.get("n_initial")
    out: list[str] = []
    t50, t90, t100 = s.get("t_evac_50"), s.get("t_evac_90"), s.get("t_evac_100")
    who = f"all {people(n0)} people" if n0 is not None else "everyone"
    if run.status == "finished" and is_num(t100):
        out.append(f"Everyone out after {seconds(t100)}: {who} left the room; half were out "
                   f"after {seconds(t50)} and 90 % after {seconds(t90)}.")
    else:
        left = s.get("n_evacuated")
        stop = s.get("t_stop")
        what = {"stopped at t_end": "stopped at its end time",
                "interrupted": "was interrupted", "failed": "failed",
                "running": "was still running when this report was made"}.get(
                    run.status, f"has status '{run.status}'")
        times = [f"{name} after {seconds(v)}" for name, v in
                 (("half were out", t50), ("90 %", t90), ("everyone", t100)) if is_num(v)]
        missed = [name for name, v in (("T50", t50), ("T90", t90), ("T100", t100))
                  if not is_num(v)]
        if missed:
            miss = ", ".join(missed[:-1]) + (" and " if len(missed) > 1 else "") + missed[-1]
            times.append(f"{miss} not reached")
        tail = "; ".join(times)
        out.append(f"The run {what} at t = {seconds(stop, '?')}, with {people(left)} of "
                   f"{people(n0)} people out; {tail}.")
    sf = run.safety
    room = run.room
    if sf is not None:
        pk = sf.get("peak_density") or {}
        if is_num(pk.get("value")):
            unit = unit_text(pk.get("unit") or "/m²")
            where = describe_place(room, pk.get("x"), pk.get("y"))
            sentence = (f"The densest place was {number(pk['value'], 3)} {unit} (averaged over "
                        f"1 m²) at t = {seconds(pk.get('t'), '?')}"
                        + (f", {where}" if where else ""))
            ta = sf.get("time_above") or {}
            if is_num(ta.get("4")):
                sentence += f"; the density was above 4 /m² for {number(ta['4'], 3)} s"
                if is_num(ta.get("6")) and ta["6"] > 0:
                    sentence += f" and above 6 /m² for {number(ta['6'], 3)} s"
            out.append(sentence + ".")
        los = sf.get("level_of_service") or {}
        if los.get("worst"):
            out.append(f"The worst level of service (Fruin, {los_scale(sf)}) "
                       f"was {los['worst']}.")
        cp = sf.get("crowd_pressure")
        if isinstance(cp, dict) and is_num(cp.get("max")):
            out.append(f"The crowd pressure (the local density times the spread of the "
                       f"people's velocities; Helbing et al. 2007 saw crowd turbulence above "
                       f"about 0.02 /s²) peaked at {number(cp['max'], 3)} "
                       f"{unit_text(cp.get('unit') or '')} at t = {seconds(cp.get('t'), '?')}.")
    else:
        msg = f"The crowd-safety measures are not available for this run ({run.safety_missing})"
        fr = run.frames
        if fr is not None:
            peak, when = fr.peak
            k = int(np.argmax(peak))
            x, y = fr.centroids[k]
            msg += (f"; the highest density in a mesh cell of the saved frames was "
                    f"{peak[k]:.1f} /m² at t = {when[k]:.0f} s, {describe_place(room, x, y)}")
        out.append(msg + ".")
    ex = [e for e in run.exits() if is_num(e["people"])]
    total = sum(float(e["people"]) for e in ex)
    if len(ex) > 1 and total > 0:
        parts = [f"'{e['name']}' {people(e['people'])} ({100 * float(e['people']) / total:.0f} %)"
                 for e in sorted(ex, key=lambda e: -float(e["people"]))]
        out.append("People per exit: " + ", ".join(parts) + ".")
    if s.get("warnings"):
        out.append(f"The run has {len(s['warnings'])} warning(s); see its settings below.")
    return out
