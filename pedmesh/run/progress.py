"""A run's progress bar: people out of all of them, the simulated time beside them, and an
estimate of the time left that knows how an evacuation goes.

tqdm's own estimate divides the people still inside by the rate they have left per second
of wall time. In an evacuation that rate is zero until the first person reaches an exit,
and it climbs as the room empties (fewer people make cheaper steps), so tqdm's estimate
is infinite first and then up to about twice the truth. :class:`EvacuationBar` splits it in
two rates it can measure: people out per *simulated* second since the first one left (a
bottleneck's flow, steady), and wall seconds per simulated second over the last second of
wall time or tenth of the run so far (what a step costs now), which falls as the room empties
(:meth:`EvacuationBar.time_left`). On Example 2 (2,400 people, about 20 s of wall time)
the social force model's estimate was at worst 1.47 and 1.31 times off (two runs) from
20 % out on, while more than 5 % of the run was left (1.76 and 1.48 when the cost was
measured over the last 3 s: it lagged behind the falling cost); eos's cost falls faster
than the estimate allows (2.9 times off at worst there, 4.8 with the 3 s).
"""

from __future__ import annotations

import sys
import time
from collections import deque

from tqdm import tqdm

__all__ = ["EvacuationBar", "progress_bar"]

#: [s] of wall time over which the cost of a simulated second is measured (at least; a
#: tenth of the time elapsed if that is longer)
COST_WINDOW_S = 1.0
#: the share of the present cost of a simulated second that the rest of the run costs on
#: average: between 1 (a cost that stays) and 1/2 (a cost in proportion to the people
#: inside), their geometric middle (:meth:`EvacuationBar.time_left`)
FALLING_COST = 0.5 ** 0.5


class EvacuationBar(tqdm):
    """tqdm's bar over the people out, with :meth:`advance` feeding the simulated time and
    :meth:`time_left` the estimate it shows (see the module docstring)."""

    def __init__(self, *args, **kwargs) -> None:
        # (set first: tqdm shows the bar from its __init__)
        self._first: tuple[float, float] | None = None  # (t_sim [s], out) at the first exit
        self._recent: deque[tuple[float, float, float]] = deque()  # (wall, t_sim [s], out)
        self._out = 0.0
        super().__init__(*args, **kwargs)

    def advance(self, out: float, t_sim: float) -> None:
        """``out`` people out at simulated time ``t_sim`` [s]."""
        if self.disable:  # (quiet: nothing shown, nothing to estimate)
            return
        shown = min(int(round(out)), self.total)
        now = time.perf_counter()
        if self._first is None and out > 0:
            self._first = (t_sim, out)
        self._out = out
        self._recent.append((now, t_sim, out))
        keep = max(COST_WINDOW_S, 0.1 * (now - self.start_t))
        while len(self._recent) > 2 and now - self._recent[1][0] >= keep:
            self._recent.popleft()
        self.update(shown - self.n)

    def time_left(self) -> float | None:
        """[s] of wall time until everyone is out at the present pace (None: nobody has
        left yet, or too little is known). The people inside over the flow since the first
        one left [ped per simulated s] is the simulated time left. A simulated second costs
        what it cost over the last few seconds, and less as the room empties: its work is
        partly per person (forces, the density), partly not (routes, the mesh). Not knowing
        the split, the estimate takes the geometric middle of the two extremes, a cost that
        stays (the time left is the cost times the simulated time left) and a cost falling
        in proportion to the people inside (half of that), so it is within a factor of
        sqrt(2) of either."""
        if self._first is None or len(self._recent) < 2:
            return None
        (w0, s0, _), (w1, s1, _) = self._recent[0], self._recent[-1]
        t_first, out_first = self._first
        if s1 <= t_first or s1 <= s0 or self._out <= out_first:
            return None
        flow = (self._out - out_first) / (s1 - t_first)  # [ped per simulated s]
        cost = (w1 - w0) / (s1 - s0)  # [wall s per simulated s], now
        return FALLING_COST * max(0.0, self.total - self._out) / flow * cost

    @property
    def format_dict(self):
        d = super().format_dict
        left = self.time_left()
        # tqdm shows (total - n) / rate as the time left: the rate that gives ours
        d["rate"] = (max(self.total - self.n, 1e-9) / left) if left else None
        return d


def progress_bar(name: str, n_people: float, quiet: bool) -> EvacuationBar:
    """The run's progress as people out of all of them (the percentage of the evacuation,
    with the estimate of the time left of :class:`EvacuationBar`); the simulated time
    beside it."""
    tty = sys.stderr.isatty()
    return EvacuationBar(total=max(1, round(float(n_people))), unit="ped", disable=quiet,
                         file=sys.stderr, dynamic_ncols=True, desc=f"{name}", leave=True,
                         mininterval=0.5 if tty else 30.0,
                         bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.0f}/{total:.0f} "
                                    "out [{elapsed}<{remaining}]{postfix}")
