"""Continuum steps land on the times the driver asks for (``MacroRun.step(t_limit)``):
exactly, never past them, with steps only ever shortened, no slivers, mass conserved; and
``step()`` without a limit is the plain CFL step, bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pedmesh.models.continuum.adapter import MacroRun
from pedmesh.models.continuum.solver import StageTooLong
from pedmesh.mesh import triangulate



@pytest.fixture(scope="module")
def room_mesh(load_shipped):
    room = load_shipped("l_shaped.json")
    return room, triangulate(room, max_area=2.0, feature_area=None)  # (coarse, uniform)


def new_run(room_mesh, model="pw", **overrides):
    room, mesh = room_mesh
    return MacroRun(room, mesh, overrides, model=model)


def spy(run):
    """Record (CFL dt, dt tried) of every step: max_dt's value and each solver.step call."""
    log = []
    solver = run.solver
    max_dt, step = solver.max_dt, solver.step

    def max_dt_spy(*a, **k):
        v = max_dt(*a, **k)
        log.append([v])
        return v

    def step_spy(state, dt):
        log[-1].append(dt)
        return step(state, dt)

    solver.max_dt, solver.step = max_dt_spy, step_spy
    return log


@pytest.mark.parametrize("model", ["pw", "rdue"])
def test_steps_land_exactly_on_each_target(room_mesh, model):
    run = new_run(room_mesh, model, cfl=0.5)  # (short steps: several per gap)
    log = spy(run)
    n0 = run.n_initial
    # 0.1 + 0.2 and 0.7 / 3 are not the decimals they look like: landing must still be exact
    targets = [0.1 + 0.2, 0.7, 0.7 + 1e-3, 1.0, 1 + 2 / 3, 2.5, 3.0]
    steps_to = []
    for target in targets:
        n = 0
        while run.t < target:
            before = run.t
            run.step(target)
            n += 1
            cfl_dt, *tried = log[-1]
            dt = tried[-1]
            assert before < run.t <= target  # never past it
            assert all(d <= cfl_dt for d in tried)  # only ever shortened
            if run.t < target:  # not landing: no sliver left for the next step
                assert target - run.t >= 0.1 * dt
                assert dt >= 0.5 * cfl_dt or len(tried) > 1
        assert abs(run.t - target) < 1e-12 and run.t == target
        steps_to.append(n)
    assert steps_to[2] == 1  # 1 ms: one short step
    assert max(steps_to) > 2  # and the longer gaps took several CFL steps
    assert run.max_mass_error < 1e-12
    assert run.remaining + run.evacuated == pytest.approx(n0, rel=1e-12)


def _old_advance(c):
    """The controller's step before t_limit existed (a copy of the old code path)."""
    s = c.solver
    s.update_route(c.state.Q, c.state.t)  # (the time: for route_interval)
    s.update_active_set(c.state.Q)
    dt = s.max_dt(c.state.Q, c.state.t)
    if not np.isfinite(dt) or dt <= 0:
        dt = 1e-2
    for _ in range(40):
        try:
            s.step(c.state, dt)
            break
        except StageTooLong as e:
            c.retried += 1
            dt = min(s.cfl * e.dt_fe, 0.9 * dt)
    c.dt_last = dt


def test_without_a_limit_nothing_changes_bitwise(room_mesh):
    runs = [new_run(room_mesh) for _ in range(4)]
    for _ in range(8):
        runs[0].step()
        runs[1].step(math.inf)
        runs[2].step(1e6)  # far away: never shortens
        _old_advance(runs[3].controller)
    ref = runs[3].state
    assert ref.t > 0.5
    for r in runs[:3]:
        assert r.state.t == ref.t and r.state.steps == ref.steps
        assert np.array_equal(r.state.Q, ref.Q)
        assert np.array_equal(r.state.outflow, ref.outflow)


def test_a_refused_landing_step_retries_shorter_and_lands_next(room_mesh):
    """A landing step refused by a stage is retried shorter (0.9 of it at most): it stops
    short, leaving over a tenth of the step, and the next step lands."""
    run = new_run(room_mesh)
    run.step()
    run.solver.update_route(run.state.Q)  # as the step will: then its CFL dt
    target = run.t + 0.8 * run.solver.max_dt(run.state.Q, run.t)  # within one CFL step
    real = run.solver.step
    refused = []

    def refuse_once(state, dt):
        if not refused:
            refused.append(dt)
            raise StageTooLong(dt_fe=dt)  # retry: min(cfl * dt, 0.9 dt)
        return real(state, dt)

    run.solver.step = refuse_once
    t0, retried = run.t, run.controller.retried
    run.step(target)
    assert refused == [target - t0]  # the refused step was the landing one
    assert run.controller.dt_last <= 0.9 * refused[0]
    assert run.controller.retried == retried + 1
    assert run.t < target and target - run.t >= 0.1 * run.controller.dt_last
    run.step(target)
    assert run.t == target
    assert run.max_mass_error < 1e-12


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan")])
def test_a_limit_not_ahead_is_an_error(room_mesh, bad):
    run = new_run(room_mesh)
    while run.t < 0.2:
        run.step(0.2)
    with pytest.raises(ValueError, match="t_stop must be later than the current time"):
        run.step(bad if bad != 0.0 else run.t)
    assert run.t == 0.2


def _next_cfl_dt(run):
    run.solver.update_route(run.state.Q)  # as the step will: then its CFL dt
    run.solver.update_active_set(run.state.Q)
    return run.solver.max_dt(run.state.Q, run.t)


def test_a_step_that_would_leave_a_sliver_is_halved(room_mesh):
    run = new_run(room_mesh)
    run.step()
    t0 = run.t
    target = t0 + 1.05 * _next_cfl_dt(run)  # one CFL step would leave 0.05 of a step
    run.step(target)
    first = run.t - t0
    assert first == pytest.approx(0.5 * (target - t0), rel=1e-12)
    run.step(target)
    assert run.t == target and run.t - t0 - first == pytest.approx(first, rel=1e-9)


def test_lands_where_t_plus_the_rest_rounds_off(room_mesh):
    """From a = 0.0325... the rest to T = 0.1230... does not add back up to T in floating
    point (a + (T - a) != T): the step still ends on T itself."""
    a, T = 0.03257964863613815, 0.12309786809084107
    assert a + (T - a) != T
    run = new_run(room_mesh)
    run.step(a)
    assert run.t == a
    assert T - a < _next_cfl_dt(run)  # one landing step
    run.step(T)
    assert run.t == T and run.state.steps == 2
