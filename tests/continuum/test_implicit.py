"""The semi-implicit (IMEX) step and the active set (:mod:`pedmesh.models.continuum.implicit`,
``FVOptions.implicit_pressure``, ``FVOptions.active_set``): convergence to the explicit
scheme as dt -> 0 with the observed order, stability far beyond the explicit (acoustic)
time step on a dam break against vacuum, the steady queue of the explicit scheme kept at
large steps, positivity and mass to round-off, and the active set's answer."""

from __future__ import annotations

import numpy as np
import pytest

from pedmesh import Exit, Room
from pedmesh.models.continuum import macro_model
from pedmesh.models.continuum.quadrature import cell_averages
from pedmesh.models.continuum.solver import FVController, FVOptions, FVSolver, FVState

from fvhelpers import no_route
from pedmesh.mesh import triangulate


def _east(x, y):
    """The desired direction: everybody towards +x."""
    e = np.zeros(np.shape(x) + (2,))
    e[..., 0] = 1.0
    return e


def _fixed_steps(mesh, model, init, t_end, dt, options, direction=no_route):
    """Steps of exactly ``dt`` (the last one shorter) from the cell averages of ``init``."""
    s = FVSolver(mesh, model, options, direction=direction)
    st = FVState(cell_averages(mesh, init, subdivisions=2))
    FVController(s, st)  # (the outflow bookkeeping)
    while st.t < t_end - 1e-12:
        s.update_active_set(st.Q)
        s.step(st, min(dt, t_end - st.t))
    return s, st


@pytest.fixture(scope="module")
def box():
    return triangulate(Room([(-3, -3), (3, -3), (3, 3), (-3, 3)]), max_area=0.08)


def _bump(x, y):
    rho = 1.0 + 2.0 * np.exp(-(x * x + y * y))
    return np.stack([rho, 0 * x, 0 * x], -1)


def test_converges_to_the_explicit_scheme_as_dt_shrinks(box):
    """A smooth bump of a crowd with the mean-field pressure (sound at 5 m/s) spreads in a
    closed room. The explicit scheme at a small step is the reference; the semi-implicit
    one at dt, dt/2, dt/4 (from beyond the explicit acoustic limit) converges to it at the
    observed order of its splitting, 1."""
    model = macro_model("mac2-local", tau=0.5)
    T = 0.6
    _, ref = _fixed_steps(box, model, _bump, T, 0.002, FVOptions(implicit_pressure=0))
    s_ex = FVSolver(box, model, FVOptions(implicit_pressure=0), direction=no_route)
    dt_acoustic = s_ex.max_dt(ref.Q) / s_ex.cfl  # the explicit positivity bound
    errs = []
    dts = [0.06, 0.03, 0.015, 0.0075]
    for dt in dts:
        _, st = _fixed_steps(box, model, _bump, T, dt, FVOptions())
        errs.append(np.sum(box.areas * np.abs(st.Q[:, 0] - ref.Q[:, 0])) / np.sum(box.areas))
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    print(f"\nIMEX vs explicit, L1(rho): {['%.2e' % e for e in errs]}, orders "
          f"{np.round(orders, 2)}, explicit bound {dt_acoustic:.3f} s")
    assert dts[0] > 2.5 * dt_acoustic  # the largest step is far beyond the explicit one
    assert all(a > b for a, b in zip(errs, errs[1:]))
    assert 0.8 < orders[-1] < 1.5  # first order: the splitting of the pressure


def test_dam_break_against_vacuum_is_stable_at_the_material_time_step():
    """A crowd at 4 ped/m^2 behind a dam, empty space ahead (mac2-local: sound at 5.9 m/s,
    eos: 2.3 m/s). The semi-implicit run takes steps set by the crowd's own speed, several
    times the explicit acoustic step, and stays bounded and positive with mass to
    round-off. With eos its profile is the explicit one within 5 % (L1); with the
    mean-field pressure (Mach 4 at the front) its implicit pressure flux carries the front
    further than the speed cap lets the explicit scheme (7.6 m against 5.7 m after 3 s,
    10 % in L1): the scheme is built for crowds, not for strong rarefactions."""
    room = Room([(-10, 0), (28, 0), (28, 2), (-10, 2)])
    mesh = triangulate(room, max_area=0.1)
    x = mesh.centroids[:, 0]

    def init(x, y):
        return np.stack([np.where(x < 0, 4.0, 0.0), 0 * x, 0 * x], -1)

    for name in ("mac2-local", "eos", "mac1"):
        model = macro_model(name)
        out = {}
        for imp in (0, 1):
            s = FVSolver(mesh, model, FVOptions(implicit_pressure=imp), direction=_east)
            st = FVState(cell_averages(mesh, init, subdivisions=2))
            c = FVController(s, st)
            n0 = s.mass(st.Q)
            steps = 0
            while st.t < 3.0 - 1e-12:
                c.advance(3.0)
                steps += 1
                assert st.Q[:, 0].min() >= 0.0
                assert np.all(np.isfinite(st.Q))
            assert abs(s.mass(st.Q) - n0) / n0 < 1e-12
            speed = np.hypot(*model.velocity(st.Q).T)
            assert speed.max() <= model.u_max * (1 + 1e-12)
            out[imp] = (steps, st.Q[:, 0].copy())
        (n_ex, rho_ex), (n_im, rho_im) = out[0], out[1]
        front_ex, front_im = x[rho_ex > 0.1].max(), x[rho_im > 0.1].max()
        print(f"\n{name} dam break: {n_ex} explicit steps, {n_im} semi-implicit; front "
              f"{front_ex:.2f} / {front_im:.2f} m")
        l1 = np.sum(mesh.areas * np.abs(rho_im - rho_ex)) / np.sum(mesh.areas * rho_ex)
        print(f"L1 difference {l1:.3f}")
        assert n_im * 2 < n_ex
        assert front_im >= front_ex - 0.5  # (a front is never held back)
        if name == "eos":
            assert l1 < 0.05 and abs(front_im - front_ex) < 1.0


def test_steady_queue_at_a_wall_is_the_explicit_one():
    """Walking into a wall (e = +x, closed room), the crowd settles where its pressure
    balances the drive: grad p = rho U_e / tau. The semi-implicit step at its large time
    step must settle on the explicit scheme's queue (the Rhie-Chow mass flux keeps the
    balance; without it the queue would be off by O(dt))."""
    room = Room([(0, 0), (12, 0), (12, 2), (0, 2)])
    mesh = triangulate(room, max_area=0.1)
    x = mesh.centroids[:, 0]
    model = macro_model("eos")

    def init(x, y):
        return np.stack([np.where(x < 6, 2.0, 0.0), 0 * x, 0 * x], -1)

    prof = {}
    for imp in (0, 1):
        s = FVSolver(mesh, model, FVOptions(implicit_pressure=imp), direction=_east)
        st = FVState(cell_averages(mesh, init, subdivisions=2))
        c = FVController(s, st)
        dts = []
        while st.t < 40.0 - 1e-12:
            dts.append(c.advance(40.0))
        bins = np.linspace(0, 12, 25)
        k = np.digitize(x, bins)
        prof[imp] = np.array([np.average(st.Q[k == j, 0], weights=mesh.areas[k == j])
                              for j in range(1, len(bins))])
        prof[f"dt{imp}"] = np.median(dts)
    diff = np.abs(prof[1] - prof[0]).max()
    print(f"\nqueue at a wall: explicit dt {prof['dt0']:.3f} s, semi-implicit dt "
          f"{prof['dt1']:.3f} s, largest difference {diff:.3f} ped/m^2 (peak "
          f"{prof[0].max():.2f})")
    assert prof["dt1"] > 1.5 * prof["dt0"]
    assert prof[0].max() > 3.0  # a real queue
    assert diff < 0.03 * prof[0].max()


def test_correction_conserves_mass_and_keeps_density_non_negative(box):
    """The implicit correction alone, on rough states at steps far beyond the acoustic one:
    mass to round-off (no exit here), rho >= 0, cells outside the active set untouched."""
    from pedmesh.models.continuum.implicit import ImplicitPressure

    rng = np.random.default_rng(5)
    m = box.n_triangles
    for name in ("eos", "mac2-local", "pw", "mac1"):
        model = macro_model(name)
        imp = ImplicitPressure(box, model)
        for trial in range(4):
            rho = 6.0 * rng.random(m) ** 3
            rho[rng.random(m) < 0.3] = 0.0
            V = np.stack([rho, rho * rng.normal(size=m), rho * rng.normal(size=m)], 1)
            Rq = rng.normal(scale=5.0, size=(m, 2))
            cact = rng.random(m) < (0.7 if trial % 2 else 1.0)
            e2t = box.edge_triangles
            live = cact[e2t[:, 0]] & ((e2t[:, 1] < 0) | cact[np.maximum(e2t[:, 1], 0)])
            out = imp.correct(V, Rq, 0.3, cact, imp.live_faces(live))
            assert out[:, 0].min() >= 0.0
            assert np.sum(box.areas * out[:, 0]) == pytest.approx(np.sum(box.areas * rho),
                                                                  rel=1e-13)
            np.testing.assert_array_equal(out[~cact], V[~cact])
        assert imp.stats["solves"] > 0


def test_active_set_gives_the_answer_of_the_whole_mesh():
    """A crowd in one corner of a room with an exit: the active set covers a fraction of the
    cells, and the run matches the one that updates every cell (the cells it leaves alone
    hold less than active_eps), with mass to round-off."""
    room = Room([(0, 0), (30, 0), (30, 10), (0, 10)], exits=[Exit("door", [(30, 4), (30, 6)])])
    mesh = triangulate(room, max_area=0.3)
    x = mesh.centroids[:, 0]

    def init(x, y):
        return np.stack([np.where(x < 6, 2.0, 0.0), 0 * x, 0 * x], -1)

    res = {}
    for act in (0, 1):
        model = macro_model("eos")
        s = FVSolver(mesh, model, FVOptions(active_set=act), direction=_east)
        st = FVState(cell_averages(mesh, init, subdivisions=2))
        c = FVController(s, st)
        n0 = s.mass(st.Q)
        frac = []
        while st.t < 8.0 - 1e-12:
            c.advance(8.0)
            frac.append(s.n_active / mesh.n_triangles)
            assert st.Q[:, 0].min() >= 0.0
        assert abs(s.mass(st.Q) + st.outflow.sum() - n0) / n0 < 1e-12
        res[act] = (st.Q.copy(), np.mean(frac))
    (Q0, f0), (Q1, f1) = res[0], res[1]
    print(f"\nactive set: {f1:.2f} of the cells on average; largest density difference "
          f"{np.abs(Q1[:, 0] - Q0[:, 0]).max():.2e}")
    assert f0 == 1.0 and f1 < 0.6
    assert np.abs(Q1[:, 0] - Q0[:, 0]).max() < 1e-3
    assert np.sum(mesh.areas * np.abs(Q1[:, 0] - Q0[:, 0])) < 1e-3 * np.sum(mesh.areas * Q0[:, 0])
    assert x[Q1[:, 0] > 0.01].max() > 12  # (the crowd did move)


def test_options_are_checked(box):
    from pedmesh.errors import ParameterError

    for bad in ({"stages": 4}, {"stages": True}, {"stages": "2"}, {"implicit_pressure": 2},
                {"active_set": 0.5}, {"active_eps": -1.0}, {"active_eps": float("nan")}):
        with pytest.raises(ParameterError):
            FVOptions(**bad)
    with pytest.raises(ParameterError, match="no pressure law"):
        FVSolver(box, macro_model("rdue"), FVOptions(implicit_pressure=1), direction=no_route)
    # the defaults: semi-implicit (2 stages, cfl 0.9) where there is a pressure law,
    # explicit otherwise, on 2 stages unless a pressure is in the explicit fluxes
    for name, imp, stages in (("eos", True, 2), ("pw", True, 2), ("mac2-local", True, 2),
                              ("rdue", False, 2), ("mac1", True, 2),
                              ("mac2-nonlocal", False, 2)):
        s = FVSolver(box, macro_model(name), FVOptions(), direction=no_route)
        assert (s.implicit is not None) == imp and s.stages == stages, name
    # mac1 with its repulsion all in the sources (imex=0): the explicit scheme
    s = FVSolver(box, macro_model("mac1", imex=0), FVOptions(), direction=no_route)
    assert s.implicit is None and s.stages == 2
    s = FVSolver(box, macro_model("eos"), FVOptions(implicit_pressure=0), direction=no_route)
    assert s.implicit is None and s.stages == 3 and s.cfl == 0.7


def test_mac1_split_repulsion_converges_in_dt_and_to_the_explicit_mac1(box):
    """mac1's repulsion split into its local part, the pressure gamma1 rho^2 / 2 treated
    implicitly, and the rest as an explicit source (imex=1, the default): on the smooth bump
    in a closed room (walls through their images) the semi-implicit runs at dt, dt/2, dt/4,
    dt/8 (from beyond 3 times the explicit acoustic bound) converge to its own small-step
    run at the order of the splitting, towards 1, and that small-step run is the explicit
    mac1 (imex=0, the whole repulsion in the sources, its time step set by the sound) to
    within 1.1 % in L1, a difference of the spatial discretisation (the Rusanov viscosity of
    the sound speed) that shrinks with the mesh (0.66 % on half the cell area, measured
    once; not checked here)."""
    T = 0.6
    A = np.sum(box.areas)
    explicit = macro_model("mac1", friction=0, imex=0)
    split = macro_model("mac1", friction=0)
    _, ref_ex = _fixed_steps(box, explicit, _bump, T, 0.002, FVOptions())
    _, ref = _fixed_steps(box, split, _bump, T, 0.001, FVOptions())
    s_ex = FVSolver(box, explicit, FVOptions(), direction=no_route)
    dt_acoustic = s_ex.max_dt(ref_ex.Q) / s_ex.cfl
    mass = np.sum(box.areas * ref_ex.Q[:, 0]) / A

    def l1(a, b):
        return np.sum(box.areas * np.abs(a.Q[:, 0] - b.Q[:, 0])) / A

    errs = []
    dts = [0.06, 0.03, 0.015, 0.0075]
    for dt in dts:
        _, st = _fixed_steps(box, split, _bump, T, dt, FVOptions())
        errs.append(l1(st, ref))
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    print(f"\nmac1 split vs its small step, L1(rho): {['%.2e' % e for e in errs]}, orders "
          f"{np.round(orders, 2)}; explicit bound {dt_acoustic:.3f} s; small step vs "
          f"explicit mac1 {l1(ref, ref_ex) / mass:.2%}")
    assert dts[0] > 3 * dt_acoustic
    assert all(a > b for a, b in zip(errs, errs[1:]))
    assert all(a < b for a, b in zip(orders, orders[1:]))  # towards the asymptotic order
    assert 0.75 < orders[-1] < 1.5
    assert l1(ref, ref_ex) / mass < 0.011


@pytest.mark.parametrize("rings", [0, 1, 2, 3])
def test_active_set_kernel_is_the_rings_of_the_occupied_cells(box, rings):
    """fv_kernels.active_set against a plain reference: the cells above active_eps grown by
    ``rings`` face neighbours, the edges whose cells are all active, and their count (its
    passes alternate between two arrays, so every parity of ``rings`` is checked)."""
    from pedmesh.models.continuum import fv_kernels as K

    mesh = box
    nbr = mesh.triangle_neighbors
    e2t = np.ascontiguousarray(mesh.edge_triangles).astype(np.int64)
    rng = np.random.default_rng(rings)
    Q = np.zeros((mesh.n_triangles, 3))
    Q[rng.choice(mesh.n_triangles, 5, replace=False), 0] = 1.0
    Q[rng.choice(mesh.n_triangles, 5, replace=False), 0] = 1e-9  # below eps
    on = Q[:, 0] > 1e-6
    for _ in range(rings):
        grown = on.copy()
        for k in range(3):
            j = nbr[:, k]
            grown |= (j >= 0) & on[np.maximum(j, 0)]
        on = grown
    r = e2t[:, 1]
    live_ref = on[e2t[:, 0]] & ((r < 0) | on[np.maximum(r, 0)])
    cact = np.zeros(mesh.n_triangles, np.bool_)
    live = np.zeros(len(e2t), np.bool_)
    n = K.active_set(Q, nbr, e2t, 1e-6, rings, cact, live)
    np.testing.assert_array_equal(cact, on)
    np.testing.assert_array_equal(live, live_ref)
    assert n == on.sum() and 0 < n < mesh.n_triangles
