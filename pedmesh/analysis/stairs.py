r"""How a building run used its stairs: for each stair, how many people took it (up and
down), when the first stepped on and the last stepped off, its peak flow and the peak
density on it. Recorded by every model that runs buildings and written to summary.json
under ``"stairs"``.

A model feeds a :class:`StairUse` as it runs:

* :meth:`StairUse.enter` when people step onto a stair from a level: the social force
  model at each crossing of a stair edge (exact: one person at the step's time), a
  continuum model each step with the inflow through the stair's edges integrated over
  it (people, fractional: an estimate, within 7 % of the people who passed in the tests
  and on the office);
* :meth:`StairUse.occupancy` each sample interval with the people on each piece (a
  continuum's mass on its cells).

The measures, per stair:

* ``people`` [ped]: who stepped onto it, ``down`` from its top level and ``up`` from its
  bottom level;
* ``first`` / ``last`` [s]: the first time half a person had stepped onto it, the last
  sample at which at least half a person was on it;
* ``peak_flow`` [ped/s]: the largest number of people stepping onto it within
  :data:`FLOW_WINDOW` seconds, divided by the window, and its time ``peak_flow_t`` (the
  window's end);
* ``peak_people`` [ped] and ``peak_density`` [ped/m^2]: the most people on it at a
  sample, and that number over its area ``area_m2`` (the mean density over the stair's
  walking surface), at ``peak_density_t``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["StairUse", "FLOW_WINDOW", "OCCUPIED"]

#: [s] the window of a stair's peak flow
FLOW_WINDOW = 10.0
#: [ped] a stair counts as used (first, last) from half a person on
OCCUPIED = 0.5


class StairUse:
    """The running record of a building's stair use (see the module docstring).
    ``surface``: the building's :class:`~pedmesh.mesh.surface.SurfaceMesh`; ``building``:
    the :class:`~pedmesh.geometry.Building` (which level is each stair's top)."""

    def __init__(self, surface, building) -> None:
        self.pieces = [p.name for p in surface.pieces]
        self.stair_piece = [k for k, p in enumerate(surface.pieces) if p.kind == "stair"]
        self.area = {k: float(np.sum(surface.pieces[k].mesh.areas)) for k in self.stair_piece}
        top = {s.name: s.top.level for s in building.stairs}
        self.top_piece = {k: surface.piece_index(top[self.pieces[k]])
                          for k in self.stair_piece}
        self._in: dict[int, list[tuple[float, float, bool]]] = {k: [] for k in
                                                               self.stair_piece}
        self._peak = {k: (0.0, None) for k in self.stair_piece}
        self._last = {k: None for k in self.stair_piece}

    def is_stair(self, piece: int) -> bool:
        return piece in self._in

    def enter(self, t: float, stair: int, people: float, from_piece: int) -> None:
        """``people`` [ped] stepped onto the stair piece ``stair`` from piece
        ``from_piece`` by time ``t`` [s]."""
        if people > 0 and stair in self._in:
            self._in[stair].append((float(t), float(people),
                                    int(from_piece) == self.top_piece[stair]))

    def occupancy(self, t: float, people_per_piece: np.ndarray) -> None:
        """The people [ped] on each piece (p,) at time ``t`` [s]."""
        for k in self.stair_piece:
            n = float(people_per_piece[k])
            if n > self._peak[k][0]:
                self._peak[k] = (n, float(t))
            if n >= OCCUPIED:
                self._last[k] = float(t)

    def summary(self) -> dict[str, dict]:
        """Per stair name, the measures of the module docstring (None where never reached)."""
        out = {}
        for k in self.stair_piece:
            ev = self._in[k]
            t = np.array([e[0] for e in ev], float)
            n = np.array([e[1] for e in ev], float)
            down = float(sum(e[1] for e in ev if e[2]))
            total = float(n.sum())
            cum = np.cumsum(n)
            first = float(t[np.argmax(cum >= OCCUPIED)]) if total >= OCCUPIED else None
            flow, flow_t = _peak_window(t, n, FLOW_WINDOW)
            peak_n, peak_t = self._peak[k]
            out[self.pieces[k]] = {
                "people": total, "down": down, "up": total - down,
                "first": first, "last": self._last[k],
                "peak_flow": flow, "peak_flow_t": flow_t,
                "peak_people": peak_n, "peak_density": peak_n / self.area[k],
                "peak_density_t": peak_t, "area_m2": self.area[k],
            }
        return out


def _peak_window(t: np.ndarray, n: np.ndarray, window: float) -> tuple[float, float | None]:
    """(the largest sum of ``n`` over events in any window (t_end - window, t_end] divided
    by ``window``, that window's end); (0, None) without events."""
    if len(t) == 0:
        return 0.0, None
    order = np.argsort(t, kind="stable")
    t, n = t[order], n[order]
    cum = np.concatenate([[0.0], np.cumsum(n)])
    lo = np.searchsorted(t, t - window, side="right")  # first event inside each window
    sums = cum[np.arange(1, len(t) + 1)] - cum[lo]
    k = int(np.argmax(sums))
    return float(sums[k] / window), float(t[k])
