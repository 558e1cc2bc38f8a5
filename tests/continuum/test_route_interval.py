"""``route_interval``: the continuum route (eikonal) is re-solved only once that much
simulated time has passed since the last solve; 0 is every step (as before an interval,
now 1 s, became the default)."""

from __future__ import annotations

import numpy as np
import pytest

import pedmesh
from pedmesh.errors import ParameterError
from pedmesh.models.continuum.solver import FVOptions
from pedmesh.models import get_model
from pedmesh.mesh import triangulate


@pytest.fixture(scope="module")
def hall():
    room = pedmesh.load_room("geometries/pillar_hall.json")
    return room, triangulate(room, max_area=2.0)


def _solve_times(room, mesh, params, t_end=3.0):
    factory = get_model("eos").build
    run = factory(room, mesh, {"cfl": 0.3, **params})  # (steps well below the intervals)
    times = []
    solve = run.solver._eikonal.solve

    def counting(cost):
        times.append(run.t)
        return solve(cost)

    run.solver._eikonal.solve = counting
    starts = []
    while run.t < t_end:
        starts.append(run.t)
        run.step()
    return run, np.array(times), np.array(starts)


def test_every_step_with_interval_zero(hall):
    _, times, starts = _solve_times(*hall, {"route_interval": 0.0})
    np.testing.assert_array_equal(times, starts)


@pytest.mark.parametrize("interval", [None, 0.25, 1.0])
def test_solved_once_per_interval(hall, interval):
    params = {} if interval is None else {"route_interval": interval}
    run, times, starts = _solve_times(*hall, params)
    if interval is None:
        interval = FVOptions().route_interval
        assert interval == 1.0
    assert times[0] == 0.0
    gaps = np.diff(times)
    assert gaps.min() >= interval * (1 - 1e-9)
    # and not held longer than the interval plus one step
    assert gaps.max() < interval + 0.2
    assert len(times) < len(starts) / 2
    # the step that comes after a gap of the interval is the one that re-solves
    for t in starts:
        due = t >= times[times <= t].max() + interval * (1 - 1e-9)
        assert not due or t in times


def test_route_interval_is_checked():
    with pytest.raises(ParameterError, match="route_interval"):
        FVOptions(route_interval=-1.0)
    with pytest.raises(ParameterError, match="route_interval"):
        FVOptions(route_interval=float("nan"))
