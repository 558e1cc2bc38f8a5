"""The social force simulation: the paper's moment proposition, rerouting, determinism,
bad input and the run contract."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from pedmesh import Exit, ParameterError, Room, SimulationError, StartArea
from pedmesh.models.sfm import SFMNumerics, Simulation, SocialForceParams
from pedmesh.run import RunInterrupted, run_model
from pedmesh.mesh import triangulate


def test_moment_proposition():
    """Constant u_e, no walls, interacting pedestrians: mass is conserved and
    M1(t) = (M1(0) - u_e) exp(-t/tau) + u_e (paper, Proposition 'moment')."""
    room = Room([(-200, -200), (200, -200), (200, 200), (-200, 200)],
                exits=[Exit("far", [(200, -10), (200, 10)])])
    mesh = triangulate(room, max_area=400.0)
    rng = np.random.default_rng(0)
    g = np.arange(-5, 5) * 0.45  # 100 pedestrians 0.45 m apart: strongly interacting
    x = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2) + rng.normal(0, 0.03, (100, 2))
    v = rng.normal(0, 0.8, (100, 2))
    ue = np.array([0.8, -0.3])
    dt = 0.002
    sim = Simulation(mesh, x, v, desired_velocity=ue, numerics=SFMNumerics(dt=dt))
    tau = sim.params.tau
    M0 = v.mean(axis=0)
    z = dt / tau
    R = 1 - z + z * z / 2 - z**3 / 6  # the SSP-RK3 amplification factor of dM/dt = (ue - M)/tau
    worst_exact = worst_rk = 0.0
    pair_work = 0.0
    for step in range(1, 5001):  # 10 s
        sim.step()
        M1 = sim.velocities.mean(axis=0)
        exact = (M0 - ue) * math.exp(-step * dt / tau) + ue
        discrete = (M0 - ue) * R**step + ue
        worst_exact = max(worst_exact, np.abs(M1 - exact).max() / np.hypot(*exact))
        worst_rk = max(worst_rk, np.abs(M1 - discrete).max() / np.hypot(*discrete))
        if step == 250:
            pair_work = np.abs(sim._F[:100] - (ue - sim.v[:100]) / tau).max()
    assert sim.n == 100  # mass conserved: nobody left, nobody added
    assert worst_exact <= 1e-8
    assert worst_rk <= 1e-12  # the pair forces cancel to round-off
    assert pair_work > 1e-3  # ... although they are far from zero individually


def test_rerouting_moves_people_to_the_free_exit():
    """Two equal exits; the crowd starts closer to the low one. Re-solving the routes from
    the density sends more people to the free high exit and empties the room sooner. (With
    the paper's beta = 0.05 the cost of a 5 ped/m^2 jam is only exp(0.25) = 1.28 times the
    free cost, so the shift is modest: 27 % -> 34 % here.)"""
    room = Room(
        [(0, 0), (60, 0), (60, 20), (0, 20)],
        exits=[Exit("low", [(60, 3), (60, 6)]), Exit("high", [(60, 14), (60, 17)])],
        start_areas=[StartArea("crowd", [(2, 1), (30, 1), (30, 9.9), (2, 9.9)], spacing=0.7)],
    )
    mesh = triangulate(room, max_area=0.5)
    share, t_last = {}, {}
    for reroute in (False, True):
        sim = Simulation(mesh, reroute=reroute)
        sim.run(600.0)
        assert sim.n == 0
        share[reroute] = float(np.mean(sim.exit_id == 1))
        t_last[reroute] = float(np.max(sim.exit_time))
    assert share[False] < 0.5  # most people use the nearer, low exit
    assert share[True] > share[False] + 0.03
    assert t_last[True] < t_last[False]


def test_identical_runs_identical_outputs(geometries_dir, load_shipped, tmp_path):
    room = load_shipped("corridor_bottleneck.json")
    mesh = triangulate(room)
    outs = []
    for k in range(2):
        out = tmp_path / f"run{k}"
        run_model(room, mesh, "sfm", t_end=30.0, out_dir=out, quiet=True,
                  overrides={"output_interval": 2.0})
        outs.append(out)
    a, b = outs
    for name in ("evacuation.csv", "trajectories.txt"):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    sa = json.loads((a / "summary.json").read_text())
    sb = json.loads((b / "summary.json").read_text())
    for s in (sa, sb):
        s.pop("wall_time_s")
        s.pop("time_split_s")
    assert sa == sb
    import pyvista as pv

    fa = sorted((a / "pedestrians").glob("*.vtp"))
    fb = sorted((b / "pedestrians").glob("*.vtp"))
    assert len(fa) == len(fb) == 16
    for p, q in zip(fa, fb):
        ma, mb = pv.read(p), pv.read(q)
        np.testing.assert_array_equal(ma.points, mb.points)
        np.testing.assert_array_equal(ma.point_data["velocity"], mb.point_data["velocity"])


@pytest.mark.parametrize("stages", [1, 3])
def test_step_densities_are_the_kernel_density_at_the_step_start(load_shipped, stages):
    """The densities a step reports (and, with density_stages=1, uses for U_e in all three
    stages) come from the per-step pair list; they equal the kernel density evaluated
    directly at the positions the step started from."""
    room = load_shipped("example2.json")
    sim = Simulation(triangulate(room), numerics=SFMNumerics(density_stages=stages))
    for _ in range(30):
        x0 = sim.positions
        sim.step()
    assert sim.n == sim.n_initial
    from scipy.spatial import cKDTree

    R = sim.params.R
    D = cKDTree(x0).sparse_distance_matrix(cKDTree(x0), sim.rc_d, output_type="coo_matrix")
    w = np.exp(-(D.data / R) ** 2) / (math.pi * R * R)
    w[D.row == D.col] = 0.0  # the pedestrian itself is added below (distance 0 is not stored)
    direct = np.bincount(D.row, weights=w, minlength=len(x0)) + 1.0 / (math.pi * R * R)
    np.testing.assert_allclose(sim.densities, direct, rtol=1e-12)
    assert direct.max() > 1.5 / (math.pi * R * R)  # a crowd, not isolated pedestrians


def test_start_outside_or_in_obstacle_is_rejected(load_shipped):
    mesh = triangulate(load_shipped("example3.json"), max_area=4)
    with pytest.raises(SimulationError,
                       match=r"pedestrian 1 starts at \(75.000, 25.000\) m, outside"):
        Simulation(mesh, np.array([[10.0, 10.0], [75.0, 25.0]]))
    with pytest.raises(SimulationError, match="pedestrian 0 starts at .* outside"):
        Simulation(mesh, np.array([[-1.0, 10.0]]))


def test_overlapping_start_is_rejected(load_shipped):
    mesh = triangulate(load_shipped("example3.json"), max_area=4)
    with pytest.raises(SimulationError, match="pedestrians 0 and 1 overlap: 0.100 m apart"):
        Simulation(mesh, np.array([[10.0, 10.0], [10.1, 10.0]]))
    Simulation(mesh, np.array([[10.0, 10.0], [10.27, 10.0]]))  # within the 5 cm tolerance


@pytest.mark.parametrize("bad", [{"m": -60.0}, {"tau": 0.0}, {"A": float("nan")},
                                 {"U_f": float("inf")}])
def test_bad_physical_parameters(bad):
    with pytest.raises(ParameterError, match=f"parameter '{next(iter(bad))}'"):
        SocialForceParams(**bad)


@pytest.mark.parametrize("bad", [{"dt": 0.0}, {"route_interval": -1.0}, {"dt": float("nan")},
                                 {"density_stages": 2}])
def test_bad_numerics(bad):
    with pytest.raises(ParameterError, match=f"parameter '{next(iter(bad))}'"):
        SFMNumerics(**bad)


def test_blow_up_stops_with_a_message_and_keeps_output(load_shipped, tmp_path):
    room = load_shipped("corridor_bottleneck.json")
    with pytest.raises(SimulationError, match=r"blow-up at t = .* s: .*smaller time step"):
        run_model(room, triangulate(room), "sfm", out_dir=tmp_path, quiet=True,
                  overrides={"max_speed": 0.5})
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["status"] == "failed" and "blow-up" in s["error"]
    assert (tmp_path / "evacuation.csv").read_text().startswith("t,evacuated\n0.000000,0")


def test_stop_request_ends_the_run_after_the_step(load_shipped, tmp_path, monkeypatch):
    """A stop request (what the CLI's Ctrl-C / SIGTERM handler sends) ends the run at the
    next step boundary with everything written; a second request interrupts at once."""
    from pedmesh.models.sfm import adapter as models
    from pedmesh.run.driver import request_stop, stop_on_signals

    room = load_shipped("corridor_bottleneck.json")
    calls = {"n": 0}
    orig = models.SFMRun.step

    def step(self, *args):
        orig(self, *args)
        calls["n"] += 1
        if calls["n"] == 300:
            request_stop()

    monkeypatch.setattr(models.SFMRun, "step", step)
    with stop_on_signals():
        with pytest.raises(RunInterrupted, match="interrupted at t = 3.00 s"):
            run_model(room, triangulate(room), "sfm", out_dir=tmp_path, quiet=True)
        with pytest.raises(KeyboardInterrupt):  # the request still stands: a second one
            request_stop()
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["status"] == "interrupted" and s["t_stop"] == pytest.approx(3.0)
    assert calls["n"] == 300
    request_stop()  # outside the block the flag was cleared: this only sets it again
    with stop_on_signals():  # ... and entering a block clears it
        pass


def test_interrupted_run_keeps_output(load_shipped, tmp_path, monkeypatch):
    from pedmesh.models.sfm import adapter as models

    room = load_shipped("corridor_bottleneck.json")
    calls = {"n": 0}
    orig = models.SFMRun.step

    def step(self, *args):
        calls["n"] += 1
        if calls["n"] == 700:
            raise KeyboardInterrupt
        orig(self, *args)

    monkeypatch.setattr(models.SFMRun, "step", step)
    with pytest.raises(RunInterrupted, match="interrupted at t = 6.99 s"):
        run_model(room, triangulate(room), "sfm", out_dir=tmp_path, quiet=True)
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["status"] == "interrupted" and s["t_stop"] == pytest.approx(6.99)
    rows = (tmp_path / "evacuation.csv").read_text().splitlines()
    assert rows[0] == "t,evacuated" and len(rows) >= 70
    from pedmesh.io import read_pvd_index

    assert len(read_pvd_index(tmp_path / "pedestrians.pvd")) == 7  # t = 0, 1, ..., 6


@pytest.mark.parametrize("leave", ["none", "first", "last", "some", "all"])
def test_leavers_are_dropped_as_fancy_indexing_would(leave):
    """kernels.compact removes those who left from every per-pedestrian array in one pass,
    the others moved up in their order: what ``arr[:m] = arr[keep]`` gives, array by
    array, and the rows beyond the first n untouched."""
    from pedmesh.models.sfm import kernels as K

    rng = np.random.default_rng(3)
    N, n = 50, 40
    exit_of = np.full(N, -1, np.int64)
    gone = {"none": [], "first": [0], "last": [n - 1], "some": [0, 3, 4, 17, 39],
            "all": list(range(n))}[leave]
    exit_of[gone] = 1
    arrays = [rng.random((N, 2)), rng.random((N, 2)), rng.random(N), rng.random(N),
              rng.random(N), rng.random(N), rng.integers(0, 9, N), rng.random((N, 2)),
              rng.permutation(N).astype(np.int64), rng.integers(0, 99, N), rng.random(N)]
    keep = np.flatnonzero(exit_of[:n] < 0)
    want = []
    for a in arrays:
        b = a.copy()
        b[:len(keep)] = a[keep]
        want.append(b)
    m = K.compact(exit_of, n, *arrays)
    assert m == len(keep)
    for a, b in zip(arrays, want):
        np.testing.assert_array_equal(a, b)
