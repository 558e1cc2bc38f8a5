"""The SFM's measured equation of state, the exact vacuum exit flux and the eos model."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from pedmesh import Exit, Room, StartArea
from pedmesh.calibration import (
    CalibrationOptions,
    calibrate,
    eos_pressure,
    fit_eos,
    lattice_virial,
    load_eos,
    pedestrian_stress,
    periodic_virial,
    save_eos,
)
from pedmesh.errors import ParameterError, PedmeshError
from pedmesh.models.continuum.physics import SFMRepulsion, gamma1
from pedmesh.models.continuum.barotropic import PressureLaw, vacuum_godunov
from pedmesh.models.sfm.params import SocialForceParams
from pedmesh.mesh import triangulate

P = SocialForceParams()
G1 = gamma1(SFMRepulsion(A=P.A, B=P.B, k=P.k, m=P.m, r_ij=2 * P.r))


def _phi(d):
    """Repulsive pair force per unit mass [m/s^2] at distance d (hand-written)."""
    return (P.A * math.exp((2 * P.r - d) / P.B) + P.k * max(2 * P.r - d, 0.0)) / P.m


def _lattice(nx, ny, a):
    """A perfect triangular lattice filling a periodic nx a x ny (a sqrt(3)/2) box."""
    h = a * math.sqrt(3) / 2
    pts = [((i + 0.5 * (j % 2)) * a, j * h) for j in range(ny) for i in range(nx)]
    return np.array(pts), (nx * a, ny * h)


@pytest.mark.parametrize("a", [0.75, 0.45, 0.31, 0.28])  # 0.28 m: bodies in contact
def test_lattice_virial_equals_the_lattice_sum(a):
    x, L = _lattice(12, 14, a) if a < 0.5 else _lattice(8, 10, a)
    rho = len(x) / (L[0] * L[1])
    assert rho == pytest.approx(2 / (math.sqrt(3) * a * a))
    if min(L) < 3.6:
        x, L = _lattice(16, 18, a)
    got = periodic_virial(x, L)
    want = lattice_virial(rho)
    assert got == pytest.approx(want, rel=1e-10)
    # and by hand, the first shell alone (six neighbours at a), for the sparse lattice
    if a == 0.75:
        first = rho / 4 * 6 * a * _phi(a)
        assert got == pytest.approx(first, rel=0.02)


def test_uncorrelated_positions_give_the_mean_field_pressure():
    rng = np.random.default_rng(7)
    L, rho = 8.0, 3.0
    n = int(rho * L * L)
    vals = np.array([periodic_virial(rng.uniform(0, L, (n, 2)), L) for _ in range(60)])
    mean = vals.mean()
    se = vals.std(ddof=1) / math.sqrt(len(vals))
    want = 0.5 * G1 * rho * rho * (n - 1) / n  # N(N-1)/2 pairs, not N^2/2
    assert abs(mean - want) < 4 * se, (mean, want, se)
    assert se / want < 0.05  # the test has power


def test_vacuum_flux_is_the_dam_break_value():
    g = 8.8
    rho = np.array([0.5, 2.0, 5.0])
    c = np.sqrt(g * rho)
    laws = [PressureLaw.quadratic(g)]
    grid = np.linspace(0.05, 20.0, 400)  # the same law as a table (bisection path)
    laws.append(PressureLaw.table(grid, 0.5 * g * grid**2, g * grid))
    for law in laws:
        h_rho, h_val = law.h_table()
        q = np.column_stack([rho, 0 * rho, 0 * rho])
        F = np.empty_like(q)
        one = np.ones(3)
        vacuum_godunov(q, one, 0 * one, law.kind, law.params, 1e-3, 10.0, h_rho, h_val, F)
        np.testing.assert_allclose(F[:, 0], 8 / 27 * rho * c, rtol=2e-3 if law.kind == 2 else 1e-12)
        # the momentum flux is m u* + p(rho*) with rho* = 4/9 rho
        np.testing.assert_allclose(F[:, 1],
                                   8 / 27 * rho * c * (2 / 3) * c + 0.5 * g * (4 / 9 * rho) ** 2,
                                   rtol=4e-3 if law.kind == 2 else 1e-12)
    # isothermal: rho e^-1 c0 at rest; supersonic outflow: the state's own flux
    law = PressureLaw.isothermal(1.0)
    F = np.empty((3, 3))
    q = np.array([[2.0, 0.0, 0.0], [2.0, 6.0, 0.0], [2.0, -1.0, 0.0]])
    vacuum_godunov(q, np.ones(3), np.zeros(3), law.kind, law.params, 1e-3, 10.0, np.zeros(2),
                   np.zeros(2), F)
    # (u = -0.5 m/s inwards still leaves through the fan: rho* = 2 e^(-0.5 - 1), u* = c0)
    np.testing.assert_allclose(F[:, 0], [2 * math.exp(-1), 6.0, 2 * math.exp(-1.5)])
    # quadratic law: a state moving inwards faster than 2c has its whole fan inside: no flux
    law = PressureLaw.quadratic(g)
    c2 = math.sqrt(g * 2.0)
    q = np.array([[2.0, -2.0 * 2.05 * c2, 0.0], [2.0, -2.0 * 1.9 * c2, 0.0]])
    F = np.empty((2, 3))
    vacuum_godunov(q, np.ones(2), np.zeros(2), law.kind, law.params, 1e-3, 100.0, np.zeros(2),
                   np.zeros(2), F)
    assert np.all(F[0] == 0) and F[1, 0] > 0


def test_shipped_fit_is_monotone_and_close_to_the_measurements():
    cal = load_eos()
    rho = np.array([r["rho"] for r in cal["table"]])
    p = np.array([r["p"] for r in cal["table"]])
    fit = fit_eos(rho, p)
    assert fit == cal["fit"]  # the shipped fit is what fit_eos makes of the shipped table
    g = np.linspace(0.01, 14.0, 5000)
    pg = eos_pressure(g, cal)
    assert np.all(np.diff(pg) > 0)
    law = PressureLaw.table(fit["rho"], fit["p"], fit["dp"])
    assert np.all(law.sound_speed(g[g >= rho[0]]) > 0)
    hi = rho >= 2
    np.testing.assert_array_less(np.abs(eos_pressure(rho[hi], cal) / p[hi] - 1), 0.05)
    # and far below the mean field, as the issue says (orders of magnitude at 1-3 ped/m^2)
    mf = 0.5 * G1 * rho**2
    assert np.all(p[(rho >= 1) & (rho <= 3)] < 0.05 * mf[(rho >= 1) & (rho <= 3)])


def test_fit_of_noisy_data_is_monotone():
    rng = np.random.default_rng(1)
    rho = np.linspace(0.5, 12, 20)
    p = 0.1 * rho**3 * (1 + 0.1 * rng.standard_normal(20))
    fit = fit_eos(rho, p)
    assert np.all(np.diff(fit["p"]) > 0) and np.all(np.array(fit["dp"]) > 0)
    law = PressureLaw.table(fit["rho"], fit["p"], fit["dp"])
    assert np.all(np.diff(law.pressure(np.linspace(0.5, 12, 3000))) >= 0)


def test_pedestrian_stress_of_a_pair_by_hand():
    d = 0.5
    x = np.array([[0.0, 0.0], [d, 0.0], [30.0, 30.0]])
    S = pedestrian_stress(positions=x, velocities=np.zeros_like(x), kinetic=False)
    # r_12 = x1 - x2 = (-d, 0), f_12 = -phi e_x: r (x) f = d phi on xx, half to each
    np.testing.assert_allclose(S[0], [[0.5 * d * _phi(d), 0], [0, 0]], rtol=1e-12)
    np.testing.assert_allclose(S[1], S[0])
    assert np.all(S[2] == 0)


def test_calibrate_small_and_reload(tmp_path):
    opts = CalibrationOptions(densities=(1.0, 3.0, 6.0), n=120, replicas=2, relax_time=1.0,
                              sample_time=1.0)
    seen = []
    cal = calibrate(options=opts, progress=False, on_row=lambda c: seen.append(len(c["table"])))
    assert seen == [1, 2, 3]
    path = save_eos(cal, tmp_path / "eos.json")
    back = load_eos(path)
    assert back["status"] == "complete" and back["parameters"]["A"] == P.A
    assert np.all(np.diff(back["fit"]["p"]) > 0)
    # an interrupted calibration is refused with a clear message
    partial = dict(cal, status="incomplete")
    partial.pop("fit")
    save_eos(partial, tmp_path / "part.json")
    with pytest.raises(PedmeshError, match="incomplete calibration"):
        load_eos(tmp_path / "part.json")
    (tmp_path / "bad.json").write_text(json.dumps({"format": "x"}))
    with pytest.raises(PedmeshError, match="not a pedmesh equation-of-state"):
        load_eos(tmp_path / "bad.json")
    with pytest.raises(ParameterError, match="narrower than 3 cut-offs"):
        CalibrationOptions(densities=(1.0, 12.0), n=100)


def test_calibration_stops_between_replicas_on_request():
    """Under stop_on_signals (the CLI's Ctrl-C / SIGTERM handling) a stop request ends the
    calibration at the next replica; the densities already measured were handed to on_row."""
    from pedmesh.run.driver import request_stop, stop_on_signals

    opts = CalibrationOptions(densities=(1.0, 3.0), n=120, replicas=2, relax_time=0.5,
                              sample_time=0.5)
    seen = []

    def row(cal):
        seen.append(len(cal["table"]))
        request_stop()  # as if SIGTERM arrived while the first density was measured

    with stop_on_signals(), pytest.raises(KeyboardInterrupt):
        calibrate(options=opts, progress=False, on_row=row)
    assert seen == [1]


@pytest.fixture(scope="module")
def corridor():
    room = Room([(0, 0), (12, 0), (12, 4), (0, 4)], exits=[Exit("door", [(12, 1), (12, 3)])],
                start_areas=[StartArea("crowd", [(1, 0.5), (7, 0.5), (7, 3.5), (1, 3.5)],
                                       density=2.0)])
    return room, triangulate(room, max_area=0.3)


def test_eos_model_evacuates_with_mass_conserved(corridor, tmp_path):
    from pedmesh.run import run_model

    room, mesh = corridor
    s = run_model(room, mesh, "eos", t_end=120.0, out_dir=tmp_path / "eos", quiet=True)
    assert s["status"] == "finished" and s["exit_condition"] == "godunov"
    assert s["n_evacuated"] == pytest.approx(36.0, abs=0.5)
    assert s["mass_error_max"] < 1e-10
    assert "warnings" not in s


def test_eos_warns_about_other_parameters(corridor, tmp_path, capsys):
    from pedmesh.run import run_model

    from pedmesh.presets import get_preset

    room, mesh = corridor
    A_cal = get_preset("validated").values["A"].value  # (the default preset's calibration)
    assert A_cal != 1500.0
    s = run_model(room, mesh, "eos", overrides={"A": 1500.0, "exit": "vacuum"}, t_end=1.0,
                  out_dir=tmp_path / "eos", quiet=True)
    assert any(f"A=1500 (calibrated for {A_cal:g})" in w for w in s["warnings"])
    assert "pedmesh: warning:" in capsys.readouterr().err
    assert s["exit_condition"] == "vacuum"
