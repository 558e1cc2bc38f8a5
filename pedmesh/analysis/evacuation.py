"""Evacuation curves, evacuation times and distances between runs."""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

__all__ = ["evacuation_curve", "evacuation_times", "evacuation_times_from_curve",
           "curve_distance", "density_l1"]


def evacuation_curve(*, exit_times: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Cumulative number of pedestrians out at times ``t`` [s] from their exit times."""
    et = np.sort(np.asarray(exit_times, float)[np.isfinite(exit_times)])
    return np.searchsorted(et, np.asarray(t, float), side="right").astype(float)


def curve_distance(*, t1: np.ndarray, n1: np.ndarray, t2: np.ndarray, n2: np.ndarray,
                   n_total: float, dt: float = 0.5) -> float:
    """Mean of ``|N1(t) - N2(t)| / N`` over a common grid (step ``dt``) up to the later of the
    two ends; each curve is held at its last value after it ends."""
    end = max(float(np.max(t1)), float(np.max(t2)))
    g = np.arange(0.0, end + dt / 2, dt)
    a = np.interp(g, t1, n1)
    b = np.interp(g, t2, n2)
    return float(np.mean(np.abs(a - b)) / n_total)


def density_l1(*, mesh, rho1: np.ndarray, rho2: np.ndarray) -> float:
    """L1 distance [ped] between two cell density fields: ``sum_i |T_i| |rho1 - rho2|``."""
    return float(np.dot(mesh.areas, np.abs(np.asarray(rho1) - np.asarray(rho2))))


def evacuation_times(exit_times: np.ndarray, n_initial: int,
                     fractions: Sequence[float] = (0.5, 0.9, 1.0)) -> list[float | None]:
    """Times [s] by which the given fractions of ``n_initial`` pedestrians have left
    (``None`` if not reached): the ``ceil(f N)``-th exit time."""
    t = np.sort(np.asarray(exit_times, float)[np.isfinite(exit_times)])
    out: list[float | None] = []
    for f in fractions:
        k = max(int(math.ceil(f * n_initial - 1e-9)), 1)
        out.append(float(t[k - 1]) if len(t) >= k else None)
    return out


def evacuation_times_from_curve(t: np.ndarray, evacuated: np.ndarray, n_initial: float,
                                fractions: Sequence[float] = (0.5, 0.9, 1.0)) -> list[float | None]:
    """First times [s] at which a cumulative evacuation curve reaches ``f * n_initial``
    (linear interpolation between samples); ``None`` if not reached."""
    t = np.asarray(t, float)
    e = np.asarray(evacuated, float)
    out: list[float | None] = []
    for f in fractions:
        target = f * n_initial
        idx = np.flatnonzero(e >= target - 1e-9 * max(n_initial, 1.0))
        if len(idx) == 0:
            out.append(None)
            continue
        k = int(idx[0])
        if k == 0 or e[k] == e[k - 1]:
            out.append(float(t[k]))
        else:
            w = (target - e[k - 1]) / (e[k] - e[k - 1])
            out.append(float(t[k - 1] + min(max(w, 0.0), 1.0) * (t[k] - t[k - 1])))
    return out
