"""Full-size runs of the paper's examples (N = 2400) and the convergence checks behind the
default time step and routing interval. Slow: run with ``pytest -m slow``."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from pedmesh.models.sfm import SFMNumerics, Simulation
from pedmesh.run import evacuation_times
from pedmesh.mesh import triangulate

pytestmark = pytest.mark.slow


def _curve(sim: Simulation, grid: np.ndarray) -> np.ndarray:
    t = np.sort(sim.exit_time[np.isfinite(sim.exit_time)])
    return np.searchsorted(t, grid, side="right")


@pytest.mark.parametrize("name", ["example1.json", "example2.json", "example3.json"])
def test_paper_example_full_run(name, load_shipped):
    room = load_shipped(name)
    mesh = triangulate(room)
    sim = Simulation(mesh)
    assert sim.n_initial == 2400
    walk = room.walkable
    frames = 0

    def check(s: Simulation) -> None:
        nonlocal frames
        if s.steps % 100:  # every output frame (1 s)
            return
        frames += 1
        x = s.positions
        assert np.all(mesh.locate(x) >= 0), f"someone left the walkable area at t = {s.t}"
        assert shapely.contains_xy(walk.buffer(1e-9), x[:, 0], x[:, 1]).all()
        for o in room.obstacles:
            assert not shapely.contains_xy(o.shape, x[:, 0], x[:, 1]).any()

    sim.run(1000.0, callback=check)
    assert sim.n == 0, f"{sim.n} pedestrians still inside at t = {sim.t}"
    counts = np.bincount(sim.exit_id, minlength=len(mesh.exit_names))
    if name == "example3.json":
        assert counts.min() > 0.3 * 2400  # both exits used
    t50, t90, t100 = evacuation_times(sim.exit_time, 2400)
    print(f"\n{name}: T50 {t50:.1f} s, T90 {t90:.1f} s, T100 {t100:.1f} s, exits {counts}, "
          f"{frames} frames checked, {sim.n_reflections} reflections")


def _example2(load_shipped, **numerics):
    room = load_shipped("example2.json")
    sim = Simulation(triangulate(room), numerics=SFMNumerics(**numerics))
    sim.run(1000.0)
    assert sim.n == 0
    return sim


def _compare(load_shipped, label, **numerics):
    """Example 2 with the defaults against a run with ``numerics`` changed: the evacuation
    curves differ by less than 1 % (mean |N_out difference| / N), T50 and T90 by < 1 %."""
    a = _example2(load_shipped)
    b = _example2(load_shipped, **numerics)
    grid = np.arange(0.0, max(np.max(a.exit_time), np.max(b.exit_time)) + 1.0, 0.5)
    diff = np.abs(_curve(a, grid) - _curve(b, grid)).mean() / 2400
    ta, tb = evacuation_times(a.exit_time, 2400), evacuation_times(b.exit_time, 2400)
    print(f"\n{label}: mean |N_out difference|/N = {diff:.4%}; T50/T90/T100 {ta} vs {tb}")
    assert diff < 0.01
    for x, y in zip(ta[:2], tb[:2]):
        assert abs(x - y) < 0.01 * y


def test_default_dt_is_converged(load_shipped):
    """Halving dt changes the evacuation curve of Example 2 by less than 1 %."""
    _compare(load_shipped, "dt 0.01 vs 0.005", dt=0.005)


def test_default_route_interval_is_converged(load_shipped):
    """Re-solving the routes every 1 s instead of every 0.1 s changes the evacuation curve
    of Example 2 by less than 1 %."""
    _compare(load_shipped, "route_interval 1.0 vs 0.1 s", route_interval=0.1)


def test_density_held_over_the_step_is_converged(load_shipped):
    """Evaluating the kernel density once per step instead of at every RK stage changes the
    evacuation curve of Example 2 by less than 1 %."""
    _compare(load_shipped, "density once per step vs every stage", density_stages=3)
