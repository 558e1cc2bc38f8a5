"""The pedestrian continuum models on the FV core: RDUE and Payne-Whitham."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from pedmesh import Exit, ParameterError, Room, StartArea
from pedmesh.eikonal import EikonalSolver
from pedmesh.models.continuum import macro_model
from pedmesh.models.continuum.adapter import MacroRun, initial_density
from pedmesh.models.continuum.solver import FVController, FVOptions, FVSolver, FVState
from pedmesh.mesh import triangulate



def test_rdue_constant_density_phi_is_distance_over_speed(load_shipped):
    mesh = triangulate(load_shipped("example3.json"), max_area=2.0)
    model = macro_model("rdue")
    s = FVSolver(mesh, model)
    rho0 = 2.0
    s.update_route(np.full((mesh.n_triangles, 1), rho0))
    distance = EikonalSolver(mesh).solve(1.0)
    ue = model.U_f * math.exp(-model.beta * rho0)
    np.testing.assert_allclose(s.phi * ue, distance, rtol=1e-12)


def test_rdue_saturated_exit_passes_capacity():
    """rho above rho* = 1/beta at the exit: the demand flux passes w U_f / (e beta)."""
    w = 2.0
    room = Room([(0, 0), (20, 0), (20, w), (0, w)], exits=[Exit("end", [(20, 0), (20, w)])])
    mesh = triangulate(room, max_area=0.1)
    model = macro_model("rdue")
    s = FVSolver(mesh, model)
    st = FVState(np.full((mesh.n_triangles, 1), 30.0))
    c = FVController(s, st)
    out0 = None
    while st.t < 30.0:
        c.advance(30.0)
        if out0 is None and st.t >= 5.0:
            out0 = (st.t, st.outflow.sum())
    rate = (st.outflow.sum() - out0[1]) / (st.t - out0[0])
    capacity = w * model.U_f / (math.e * model.beta)
    assert rate == pytest.approx(capacity, rel=0.05)


def test_stage_beyond_its_forward_euler_bound_is_refused_and_the_step_retried(load_shipped):
    """Each stage checks dt against the forward-Euler bound of its own first-order wave
    speeds (the flux limiter's positivity needs it): a residual asked for a longer stage
    raises StageTooLong, and the controller retries the step shorter. At cfl = 1 the crowd
    of the corridor accelerates enough within a step to need retries; rho stays >= 0 and
    mass is conserved."""
    from pedmesh.models.continuum.solver import StageTooLong

    room = load_shipped("corridor_bottleneck.json")
    run = MacroRun(room, triangulate(room), {"cfl": 1.0, "implicit_pressure": 0}, model="pw")
    s, Q = run.solver, run.state.Q
    dt = s.max_dt(Q)  # the bound of Q, or less (pw floors the wave speeds at U_f)
    s.residual(Q, 0.0, dt)  # within the bound
    with pytest.raises(StageTooLong) as err:
        s.residual(Q, 0.0, 3.0 * dt)
    assert dt <= err.value.dt_fe < 3.0 * dt
    n0 = run.n_initial
    for _ in range(150):
        run.step()
        assert run.state.Q[:, 0].min() >= 0.0
    assert run.controller.retried > 0
    assert run.summary()["steps_retried"] == run.controller.retried
    assert abs(run.solver.mass(run.state.Q) + run.evacuated - n0) / n0 <= 1e-10


@pytest.mark.parametrize("model", ["rdue", "pw"])
def test_mass_is_conserved_every_step(load_shipped, model):
    room = load_shipped("corridor_bottleneck.json")
    run = MacroRun(room, triangulate(room), {}, model=model)
    n0 = run.n_initial
    assert n0 == pytest.approx(150.0, rel=1e-9)
    worst = 0.0
    for _ in range(150):
        run.step()
        inside = run.solver.mass(run.state.Q)
        worst = max(worst, abs(inside + run.evacuated - n0) / n0)
        assert run.state.Q[:, 0].min() >= 0.0
    assert worst <= 1e-10
    assert run.evacuated > 0


@pytest.mark.parametrize("model", ["rdue", "pw"])
def test_mirror_symmetric_room_stays_symmetric(mirrored_mesh, model):
    mesh, _, _, tmir = mirrored_mesh
    m = macro_model(model)
    s = FVSolver(mesh, m, FVOptions())
    rho0 = np.where(mesh.centroids[:, 0] < 48, 1.0, 0.0)
    st = FVState(m.initial_state(rho0))
    c = FVController(s, st)
    for _ in range(60):
        c.advance()
    Q = st.Q
    np.testing.assert_allclose(Q[:, 0], Q[tmir, 0], rtol=0, atol=1e-10)
    if m.n_vars == 3:
        np.testing.assert_allclose(Q[:, 1], Q[tmir, 1], rtol=0, atol=1e-10)
        np.testing.assert_allclose(Q[:, 2], -Q[tmir, 2], rtol=0, atol=1e-10)
    assert st.t > 3.0 and Q[:, 0].max() > 0.5


def test_initial_density_of_the_paper_block(load_shipped):
    room = load_shipped("example2.json")
    mesh = triangulate(room)
    rho = initial_density(room, mesh)
    assert np.dot(mesh.areas, rho) == pytest.approx(2400.0, rel=1e-9)
    assert rho.max() == pytest.approx(1.0) and rho.min() == 0.0


def test_unknown_and_bad_parameters(load_shipped):
    room = load_shipped("corridor_bottleneck.json")
    mesh = triangulate(room)
    with pytest.raises(ParameterError, match="unknown parameter 'c1'"):
        MacroRun(room, mesh, {"c1": 1.0}, model="pw")
    with pytest.raises(ParameterError, match="no exit condition 'demand'"):
        MacroRun(room, mesh, {"exit": "demand"}, model="pw")
    with pytest.raises(ParameterError, match="parameter 'cfl'"):
        MacroRun(room, mesh, {"cfl": 2.0}, model="rdue")
    with pytest.raises(ParameterError, match="parameter 'c0'"):
        MacroRun(room, mesh, {"c0": -1.0}, model="pw")


def test_exit_conditions_differ_for_a_pressured_crowd():
    """Empty space beyond the door lets a pressured crowd out faster than a transmissive
    (zero-gradient) exit."""
    room = Room([(0, 0), (10, 0), (10, 4), (0, 4)], exits=[Exit("door", [(10, 1.5), (10, 2.5)])],
                start_areas=[StartArea("crowd", [(5, 0), (10, 0), (10, 4), (5, 4)], density=3.0)])
    mesh = triangulate(room, max_area=0.1)
    out = {}
    for kind in ("vacuum", "transmissive"):
        run = MacroRun(room, mesh, {"exit": kind, "c0": 1.0}, model="pw")
        while run.t < 5.0:
            run.step()
        out[kind] = run.evacuated
    assert out["vacuum"] > 1.2 * out["transmissive"]


@pytest.mark.parametrize("model", ["rdue", "pw"])
def test_run_contract(geometries_dir, tmp_path, model):
    import pyvista as pv

    from pedmesh.cli import main

    out = tmp_path / model
    assert main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--model", model,
                 "--out", str(out), "-q", "--t-end", "20"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["model"] == model and s["mass_error_max"] < 1e-10
    assert s["n_initial"] == pytest.approx(150.0)
    rows = (out / "evacuation.csv").read_text().splitlines()
    # a row per step, at most every 0.1 s: 20 s give about 200 rows
    assert rows[0] == "t,evacuated" and len(rows) > min(s["steps"], 190)
    flow = (out / "outflow.csv").read_text().splitlines()
    assert flow[0] == "t,end" and len(flow) == len(rows)
    r = pv.PVDReader(out / "density.pvd")
    r.set_active_time_value(r.time_values[-1])
    g = r.read()[0]
    assert {"rho", "velocity"} <= set(g.cell_data.keys()) and "phi" in g.point_data.keys()


def _small_mesh():
    room = Room([(0, 0), (6, 0), (6, 4), (0, 4)], exits=[Exit("e", [(6, 1), (6, 3)])])
    return triangulate(room, max_area=0.05)


def _rough_state(model, mesh, seed=11):
    """Density with vacuum and near-vacuum cells (below rho_cut: desingularised velocity),
    and fast momenta."""
    rng = np.random.default_rng(seed)
    rho = 4.0 * rng.random(mesh.n_triangles)
    rho[rng.random(mesh.n_triangles) < 0.2] = 0.0
    rho[rng.random(mesh.n_triangles) < 0.1] = 1e-4
    Q = model.initial_state(rho)
    if Q.shape[1] == 3:
        Q[:, 1:] = rng.normal(scale=1.5, size=(mesh.n_triangles, 2)) * rho[:, None]
    return Q


@pytest.mark.parametrize("name", ["pw", "mac2-local", "mac1", "rdue"])
def test_fused_first_order_fluxes_equal_the_gathered_ones(name):
    """Models read the interior edges' cell averages in place for the first-order fluxes
    (``cell_flux``: one point per edge for the barotropic models, both Gauss points for
    rdue, whose flux follows the direction); the result must be the gather-then-flux
    path's, bit for bit, on a state with vacuum, near-vacuum and fast cells (rdue: to
    round-off, as the kernel projects the direction on the normal with fused multiply-adds
    where the gathered path uses numpy)."""
    mesh = _small_mesh()
    model = macro_model(name)
    s = FVSolver(mesh, model, FVOptions())
    Q = _rough_state(model, mesh)
    s.update_route(Q)
    s.residual(Q, 0.0, 1e-3)  # allocates the work arrays
    assert s._one_point_low_order(True) == (name != "rdue") and model.cell_flux is not None
    F1, a1 = np.empty_like(s._FL), np.empty_like(s._alpha)
    s._low_order(Q, 0.0, F1, a1)
    model.cell_flux = None  # the gathered path
    F2, a2 = np.empty_like(F1), np.empty_like(a1)
    s._low_order(Q, 0.0, F2, a2)
    if name == "rdue":
        np.testing.assert_allclose(F1, F2, rtol=0, atol=1e-14 * np.abs(F2).max())
        np.testing.assert_allclose(a1, a2, rtol=1e-14)
    else:
        np.testing.assert_array_equal(F1, F2)
        np.testing.assert_array_equal(a1, a2)


@pytest.mark.parametrize("name", ["pw", "mac2-local", "eos", "rdue"])
def test_one_pass_fluxes_and_sources_equal_the_generic_path(name):
    """Models integrate the high-order edge fluxes (``edge_flux``) and the barotropic ones
    average the interior-point sources (``source_mean``) in one pass each; the residual
    must be the generic path's (point fluxes, then integration; point sources, then the
    mean) to round-off."""
    mesh = _small_mesh()
    model = macro_model(name)
    s = FVSolver(mesh, model, FVOptions())
    Q = _rough_state(model, mesh)
    s.update_route(Q)
    assert model.edge_flux is not None and (model.source_mean is not None) == (name != "rdue")
    d1, o1 = s.residual(Q, 0.0, 1e-4)
    model.edge_flux = model.source_mean = None
    d2, o2 = s.residual(Q, 0.0, 1e-4)
    scale = np.abs(d2).max(axis=0)
    assert np.all(scale > 0)
    np.testing.assert_allclose(d1, d2, rtol=0, atol=1e-13 * scale.max())
    np.testing.assert_allclose(o1, o2, rtol=1e-13)


@pytest.mark.parametrize("name,implicit,exit", [
    ("eos", False, None), ("eos", True, None), ("pw", False, "godunov"),
    ("pw", True, "godunov"), ("mac2-local", False, "godunov"), ("pw", False, "vacuum")])
def test_one_pass_boundary_fluxes_equal_the_generic_path(name, implicit, exit):
    """The barotropic models do their wall and Godunov exit edges in one pass each
    (``boundary_flux``: point fluxes, integration and wave speeds); the first- and
    high-order fluxes and the wave speeds must be the generic path's to round-off, also for
    the explicit part of the semi-implicit step (whose exit wave speed is not the
    Rusanov one) and where the exit condition is not Godunov (generic path)."""
    mesh = _small_mesh()
    model = macro_model(name)
    s = FVSolver(mesh, model, FVOptions(implicit_pressure=implicit, exit=exit))
    assert (s.xmodel is not model) == implicit and s.xmodel.boundary_flux is not None
    Q = _rough_state(model, mesh)
    s.update_route(Q)
    s.residual(Q, 0.0, 1e-4)  # allocates the work arrays
    Q = Q.copy()
    Q[s.e2t[s.exits, 0], 1] = np.abs(Q[s.e2t[s.exits, 0], 1])  # crowds leaving too
    got = []
    for hook in (s.xmodel.boundary_flux, None):
        s.xmodel.boundary_flux = hook
        F, a = np.full_like(s._FL, np.nan), np.full_like(s._alpha, np.nan)
        s._low_order(Q, 0.0, F, a)
        R = s.recon
        R.apply(Q, s._Es.reshape(-1, 3), s._Vi, order=3, eps_hat=0.1, qref=s.qref,
                slot=s._slot, positivity=None, cact=s.cact)
        FH = np.full_like(s._FL, np.nan)
        s._fluxes(0.0, FH)
        got.append((F, a, FH))
    for x, y in zip(*got):
        assert np.all(np.isfinite(x))
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-14 * np.abs(y).max())
    b = np.concatenate([s.walls, s.exits])
    assert np.abs(got[0][0][s.exits, 0]).max() > 0 and np.abs(got[0][2][b]).max() > 0


def test_one_pass_hooks_step_aside_for_a_subclass_with_its_own_flux_or_source():
    from pedmesh.models.continuum.pw import PayneWhitham

    class Own(PayneWhitham):
        def source(self, q, ex, ey):
            return 2.0 * super().source(q, ex, ey)

    class OwnFlux(PayneWhitham):
        def flux(self, qL, qR, nx, ny, ex, ey):
            return super().flux(qL, qR, nx, ny, ex, ey)

    class OwnExit(PayneWhitham):
        def exit_flux(self, q, nx, ny, ex, ey, kind):
            return super().exit_flux(q, nx, ny, ex, ey, kind)

    assert Own().source_mean is None and Own().edge_flux is not None
    assert OwnFlux().edge_flux is None and OwnFlux().cell_flux is None
    assert OwnFlux().boundary_flux is None and OwnExit().boundary_flux is None
    assert OwnExit().edge_flux is not None
    assert PayneWhitham().source_mean is not None and PayneWhitham().boundary_flux is not None

    from pedmesh.models.continuum.rdue import RDUE

    class OwnRDUE(RDUE):
        def flux(self, qL, qR, nx, ny, ex, ey):
            return super().flux(qL, qR, nx, ny, ex, ey)

    assert OwnRDUE().edge_flux is None and OwnRDUE().cell_flux is None
    assert RDUE().edge_flux is not None and RDUE().cell_flux is not None


def test_density_flux_limiter_equals_the_general_one():
    """The density-only FCT (the common case) has a kernel of its own; it must give the
    general kernel's fluxes, limiter factors and divergence (here: the velocity constraints
    switched off in every cell), and the divergence must be that of its fluxes."""
    from pedmesh.models.continuum import fv_kernels as K

    mesh = _small_mesh()
    model = macro_model("pw")
    s = FVSolver(mesh, model, FVOptions(implicit_pressure=0))
    Q = _rough_state(model, mesh)
    s.update_route(Q)
    s.residual(Q, 0.0, 1e-3)
    s._fluxes(0.0, s._Fb)
    s._low_order(Q, 0.0, s._FL, s._alpha)
    dt = K.cfl_dt(s._alpha, s.lengths, s.e2t, s.t2e, s.areas, 0.9, s.cact)
    m = mesh.n_triangles
    out = []
    for use_vel in (False, True):
        F, th, dQ = np.empty_like(s._Fb), np.empty(mesh.n_edges), np.empty_like(Q)
        work = (np.empty((3, m)), np.empty((5, m)), np.empty((5, m)))
        # (a floor rho_eps = 0.2 ped/m^2 makes the limiter act on a few per cent of the edges)
        K.fct_blend(s._Fb, s._FL, s.e2t, s.t2e, s.inv_areas, Q, dt, 0.2, F, th, use_vel,
                    s._vlo, s._vhi, np.zeros(m, np.bool_), *work, dQ, s.cact, s.live)
        out.append((F, th, dQ))
    assert 0 < np.mean(out[0][1] < 1) < 0.9  # the limiter acts on some edges
    for a, b in zip(out[0], out[1]):
        # equal up to the rounding of a fused multiply-add, which LLVM may form in one
        # kernel and not in the other (fastmath "contract")
        np.testing.assert_allclose(a, b, rtol=4e-16, atol=4e-16 * np.abs(b).max())
    div = np.empty_like(Q)
    K.divergence(out[0][0], s.e2t, s.t2e, s.inv_areas, div, s.cact)
    np.testing.assert_allclose(out[0][2], div, rtol=0, atol=1e-13 * np.abs(div).max())


@pytest.mark.parametrize("name", ["pw", "mac1", "mac2-local", "mac2-nonlocal", "eos"])
def test_fluxes_declared_direction_free_ignore_the_edge_directions(name):
    """A model with ``direction_dependent_flux = False`` gets no directions at the edges
    (the solver skips sampling them); its residual must not change when they are set, at
    any of its exit conditions."""
    mesh = _small_mesh()
    rng = np.random.default_rng(3)
    for exit_kind in macro_model(name).exit_conditions:
        model = macro_model(name)
        assert not model.direction_dependent_flux
        s = FVSolver(mesh, model, FVOptions(exit=exit_kind))
        Q = _rough_state(model, mesh)
        s.update_route(Q)
        d1, o1 = s.residual(Q, 0.0, 1e-4)
        assert not np.any(s.e_edge)  # not sampled
        a = rng.uniform(0, 2 * np.pi, s.e_edge.shape[:2])
        s.e_edge = np.stack([np.cos(a), np.sin(a)], axis=-1)
        s._sample_directions()
        for hooks in (True, False):
            if not hooks:  # the generic path too
                model.edge_flux = model.cell_flux = None
            d2, o2 = s.residual(Q, 0.0, 1e-4)
            np.testing.assert_allclose(d2, d1, rtol=0, atol=1e-13 * np.abs(d1).max())
            np.testing.assert_allclose(o2, o1, rtol=1e-13)


@pytest.mark.parametrize("m", [1, 3, 4, 7, 10001])
def test_cell_total_is_the_area_weighted_sum(m):
    from pedmesh.models.continuum.fv_kernels import cell_total

    rng = np.random.default_rng(m)
    areas, Q = rng.random(m), rng.random((m, 3))
    exact = math.fsum(areas * Q[:, 0])
    # the bound of recursive summation over four partial sums of about m/4 terms each
    assert abs(cell_total(areas, Q) - exact) <= (m / 4 + 3) * 2.0**-52 * exact
