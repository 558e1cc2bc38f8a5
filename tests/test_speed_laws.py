"""Desired-speed laws (pedmesh.speed): values, the compiled kernels against the numpy
formulas, the capacity, errors, and the laws reaching every model."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pedmesh.errors import ParameterError
from pedmesh.speed import SpeedLaw, flux_and_slope, shape
from pedmesh.mesh import triangulate


def test_weidmann_values():
    w = SpeedLaw("weidmann", U_f=1.34)
    # Weidmann (1993): v(rho) = 1.34 (1 - exp(-1.913 (1/rho - 1/5.4)))
    for rho, v in ((1.0, 1.34 * (1 - math.exp(-1.913 * (1 - 1 / 5.4)))),
                   (3.0, 1.34 * (1 - math.exp(-1.913 * (1 / 3 - 1 / 5.4))))):
        assert w(rho) == pytest.approx(v, rel=1e-14)
    assert w(0.0) == 1.34 and w(5.4) == 0.0 and w(7.0) == 0.0
    assert 0.30 < float(w(3.0)) < 0.35  # the published curve: 0.33 m/s at 3 /m^2
    assert np.all(np.diff(w(np.linspace(0, 6, 200))) <= 0)  # never faster when denser
    # the largest flow of Weidmann's diagram: about 1.2 /(m s) near 1.75 /m^2
    assert 1.6 < w.capacity_density < 2.0 and 1.15 < w.capacity < 1.3


def test_exponential_is_the_papers_law():
    e = SpeedLaw()
    rho = np.linspace(0, 8, 50)
    assert np.array_equal(e(rho), 1.034 * np.exp(-0.05 * rho))
    assert e.capacity_density == 20.0
    assert e.capacity == pytest.approx(1.034 * 20 * math.exp(-1))


@pytest.mark.parametrize("law", [SpeedLaw(), SpeedLaw("weidmann", U_f=1.34),
                                 SpeedLaw("weidmann", U_f=1.2, rho_jam=6.0, gamma_w=1.5),
                                 SpeedLaw("weidmann", U_f=1.34, rho_jam=5.222, gamma_w=2.2,
                                          shift=0.65), SpeedLaw(shift=0.65)])
def test_kernels_match_the_formulas(law):
    a = law.array
    rho = np.concatenate([[0.0, 1e-9, 1e-3], np.linspace(0.05, 8.0, 157)])
    g = np.array([shape(a, r) for r in rho])
    assert np.allclose(g, law.shape(rho), rtol=1e-13, atol=1e-15)
    fd = np.array([flux_and_slope(a, law.U_f, r) for r in rho])
    assert np.allclose(fd[:, 0], law.flow(rho), rtol=1e-13, atol=1e-15)
    # |f'| against centred differences where f is smooth (away from 0 and rho_jam)
    h = 1e-6
    inner = ((rho > 1e-2) & (np.abs(rho - law.shift - law.rho_jam) > 1e-3)
             & (np.abs(rho - law.shift) > 1e-3))
    num = (law.flow(rho + h) - law.flow(rho - h)) / (2 * h)
    assert np.allclose(fd[inner, 1], np.abs(num[inner]), rtol=1e-6, atol=1e-8)


def test_route_cost_is_finite_in_a_jam():
    w = SpeedLaw("weidmann", U_f=1.34)
    c = w.route_cost(np.array([0.0, 2.0, 5.4, 9.0]))
    assert np.all(np.isfinite(c)) and c[0] == pytest.approx(1 / 1.34)
    assert c[2] == c[3] == pytest.approx(1 / (0.05 * 1.34))


@pytest.mark.parametrize("kw, match", [({"name": "linear"}, "unknown speed law 'linear'"),
                                       ({"rho_jam": 0.0}, "'rho_jam' must be positive"),
                                       ({"gamma_w": -1.0}, "'gamma_w' must be positive")])
def test_bad_laws_are_clear_errors(kw, match):
    with pytest.raises(ParameterError, match=match):
        SpeedLaw(**{"name": "weidmann", **kw})


def test_bad_speed_law_on_the_command_line(geometries_dir, tmp_path, capsys):
    from pedmesh.cli import main

    rc = main(["run", str(geometries_dir / "l_shaped.json"), "--model", "rdue", "--param",
               "speed_law=linear", "--out", str(tmp_path / "r"), "-q"])
    assert rc != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("pedmesh: error:") and "unknown speed law 'linear'" in err[-1]


def _out_after_4_s(model: str, laws: dict[str, dict]) -> dict[str, float]:
    """People out after 4 s of a crowd of 3 /m^2 right at a 4 m exit, for each of the
    ``laws`` (name: parameters), with the law checked to reach the model's summary."""
    from pedmesh import Room
    from pedmesh.models import get_model

    room = Room(outline=[(0, 0), (12, 0), (12, 4), (0, 4)],
                exits=[{"name": "out", "polyline": [(12, 0), (12, 4)]}],
                start_areas=[{"name": "crowd", "polygon": [(6, 0.3), (11.7, 0.3), (11.7, 3.7),
                                                           (6, 3.7)], "density": 3.0}])
    mesh = triangulate(room, max_area=0.5)
    out = {}
    for name, params in laws.items():
        run = get_model(model).build(room, mesh, params)
        assert run.parameters()["speed_law"] == params["speed_law"]
        while run.t < 4.0:
            run.step(4.0)
        out[name] = run.evacuated
    return out


@pytest.mark.parametrize("model", ["sfm", "rdue", "eos", "pw", "mac2-local"])
def test_every_model_takes_the_law(model):
    """The law reaches each model (its summary), and a jam-density law slows a crowd
    that is denser than the free-flow regime: fewer out after a few seconds."""
    # Weidmann's law wants 0.25 m/s at 3 /m^2 (with U_f = 1.034 m/s), the exponential
    # one 0.89 m/s
    out = _out_after_4_s(model, {law: {"speed_law": law, "U_f": 1.034}
                                 for law in ("exponential", "weidmann")})
    # (mac2-local: its mean-field pressure pushes the crowd out too, 0.9 times as many)
    assert 0 < out["weidmann"] < (0.95 if model == "mac2-local" else 0.8) * out["exponential"]


@pytest.mark.parametrize("self_share", [1, 0])
def test_a_lone_walker_and_its_own_density(self_share):
    """With density_self=1 (the paper's eq3) a lone walker feels its own kernel density,
    1/(pi R^2) = 0.65 /m^2, and walks at U_f g(0.65); with 0 it walks at U_f."""
    from pedmesh import Room
    from pedmesh.models.sfm.adapter import SFMRun

    room = Room(outline=[(0, 0), (30, 0), (30, 2), (0, 2)],
                exits=[{"name": "end", "polyline": [(30, 0), (30, 2)]}],
                start_areas=[{"name": "one", "polygon": [(0.5, 0.5), (1.5, 0.5), (1.5, 1.5),
                                                         (0.5, 1.5)], "count": 1}])
    run = SFMRun(room, triangulate(room, max_area=1.0), {"speed_law": "weidmann", "U_f": 1.34,
                                                  "density_self": self_share})
    for _ in range(500):  # 5 s: ten relaxation times
        run.sim.step()
    speed = float(np.hypot(*run.sim.v[0]))
    w0 = 1.0 / (math.pi * 0.7**2)
    want = 1.34 * float(SpeedLaw("weidmann").shape(w0)) if self_share else 1.34
    assert speed == pytest.approx(want, rel=2e-3)
    assert (speed < 1.3) == bool(self_share)


def test_rdue_with_a_jam_density_piles_no_one_above_it(load_shipped):
    """RDUE on the paper's Example 3: with the exponential law (no jam density) cells at
    the obstacle's corners and the exits fill to tens of people per m^2; with Weidmann's
    law the density stays at the jam density (within the reconstruction's overshoot)."""
    from pedmesh.models import get_model

    room = load_shipped("example3.json")
    mesh = triangulate(room)
    peak = {}
    for law in ("exponential", "weidmann"):
        run = get_model("rdue").build(room, mesh, {"speed_law": law})
        top = 0.0
        while not run.done and run.t < 300:
            run.step()
            top = max(top, float(run.state.Q[:, 0].max()))
        peak[law] = top
    assert peak["exponential"] > 20.0
    assert peak["weidmann"] <= 1.05 * 5.4


def test_the_shifted_law_is_the_law_at_rho_minus_the_shift():
    """A continuum law shifted by 1/(pi R^2) gives, at a crowd density rho, the speed a
    social force model with density_self=0 wants there if its kernel density of a crowd is
    rho less its own share (how the first validated preset matched the two; the present
    one measures the SFM's diagram instead, tests/calibration/test_fundamental_diagram.py)."""
    w0 = 1.0 / (math.pi * 0.7**2)
    law = SpeedLaw("weidmann", U_f=1.34, rho_jam=5.637, gamma_w=1.919, shift=w0)
    sfm = SpeedLaw("weidmann", U_f=1.34, rho_jam=5.637, gamma_w=1.919)
    rho = np.linspace(0.0, 6.0, 61)
    assert np.allclose(law(rho), sfm(np.maximum(rho - w0, 0.0)), rtol=1e-6)
    assert law.capacity > 1.4 * sfm.capacity  # (the shift raises the capacity)


TABLE = "0:1 0.3:0.95 0.6:0.8 1.5:0.6 2.7:0.3 5.6:0"


@pytest.mark.parametrize("law", [SpeedLaw("table", U_f=1.34, table=TABLE),
                                 SpeedLaw("table", U_f=1.2, table=TABLE, shift=0.65),
                                 SpeedLaw("table", U_f=1.34, table=[(0, 1), (2, 0.5)])])
def test_table_kernels_match_the_interpolation(law):
    """The compiled table law is numpy's piecewise-linear interpolation (constant beyond
    the last point), its flow rho U_e and |d(rho U_e)/d rho| between the points."""
    a = law.array
    rho = np.concatenate([[0.0, 1e-9], np.linspace(0.01, 8.0, 211)])
    x, g = np.asarray(law.table, float).T
    want = np.interp(np.maximum(rho - law.shift, 0.0), x, g)
    got = np.array([shape(a, r) for r in rho])
    assert np.allclose(got, want, rtol=1e-14, atol=1e-15)
    assert np.allclose(law.shape(rho), want, rtol=1e-14, atol=1e-15)
    fd = np.array([flux_and_slope(a, law.U_f, r) for r in rho])
    assert np.allclose(fd[:, 0], law.U_f * rho * want, rtol=1e-13, atol=1e-15)
    h = 1e-7
    knots = law.shift + x
    inner = (np.min(np.abs(rho[:, None] - knots[None, :]), axis=1) > 1e-4) & (rho > 1e-3)
    num = (law.flow(rho + h) - law.flow(rho - h)) / (2 * h)
    assert np.allclose(fd[inner, 1], np.abs(num[inner]), rtol=1e-5, atol=1e-7)


def test_table_law_text_and_properties():
    law = SpeedLaw("table", U_f=1.34, table=TABLE)
    assert law.table[0] == (0.0, 1.0) and law.table[-1] == (5.6, 0.0)
    assert law.jam_density == 5.6
    assert SpeedLaw("table", table=[(0, 1), (2, 0.5)]).jam_density == math.inf
    # the capacity is the largest rho U_e, on a grid as well as by the optimizer
    rho = np.linspace(0.0, 5.6, 56001)
    assert law.capacity == pytest.approx(float(np.max(law.flow(rho))), rel=1e-6)
    shifted = SpeedLaw("table", U_f=1.34, table=TABLE, shift=0.65)
    rho = np.linspace(0.0, 6.3, 63001)
    assert shifted.capacity == pytest.approx(float(np.max(shifted.flow(rho))), rel=1e-6)
    assert shifted.capacity_density == pytest.approx(rho[np.argmax(shifted.flow(rho))],
                                                     abs=2e-4)
    with pytest.raises(ParameterError, match="never reaches g = 0"):
        SpeedLaw("table", table=[(0, 1), (2, 0.5)]).capacity_density
    p = law.parameters()
    assert p["speed_law"] == "table"
    again = SpeedLaw("table", U_f=1.34, table=p["speed_table"])
    assert again.table == law.table


@pytest.mark.parametrize("table, match", [
    ("", "speed law 'table' needs its points"),
    ("0:1 1:x", "must be points rho:g"),
    ("0:1 1", "two finite numbers"),
    ("0.1:1 1:0.5", "must start at 0:1"),
    ("0:1 2:0.5 1:0.4", "densities must increase, got 1 after 2"),
    ("0:1 1:0.5 2:0.6", "g must not increase"),
    ("0:1 1:-0.1", "g must not increase and stay in \\[0, 1\\]"),
    ("0:1", "at least two points")])
def test_bad_speed_tables_are_clear_errors(table, match):
    with pytest.raises(ParameterError, match=match):
        SpeedLaw("table", table=table)


def test_bad_speed_table_on_the_command_line(geometries_dir, tmp_path, capsys):
    from pedmesh.cli import main

    rc = main(["run", str(geometries_dir / "l_shaped.json"), "--model", "sfm", "--param",
               "speed_law=table", "--param", "speed_table=0:1 1:0.5 2:0.7",
               "--out", str(tmp_path / "r"), "-q"])
    assert rc != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("pedmesh: error:") and "g must not" in err[0]


@pytest.mark.parametrize("model", ["sfm", "rdue", "eos"])
def test_a_table_law_equal_to_weidmanns_gives_the_same_run(model):
    """A table through many points of Weidmann's law runs like Weidmann's law: the same
    people out after 4 s within a few per cent (the interpolation error is ~1e-3)."""
    w = SpeedLaw("weidmann", U_f=1.34)
    pts = np.concatenate([np.linspace(0.0, 1.0, 11)[:-1], np.linspace(1.0, 5.4, 89)])
    table = " ".join(f"{r:.6g}:{float(w.shape(r)):.9g}" for r in pts)
    out = _out_after_4_s(model, {
        "weidmann": {"speed_law": "weidmann", "U_f": 1.34},
        "table": {"speed_law": "table", "speed_table": table, "U_f": 1.34}})
    assert out["table"] == pytest.approx(out["weidmann"], rel=0.03, abs=1.0)


def test_rdue_with_a_table_law_piles_no_one_above_its_jam_point(load_shipped):
    """As with Weidmann's law: a table that reaches g = 0 at 5.6 /m^2 keeps RDUE's
    Example 3 at that density (within the reconstruction's overshoot)."""
    from pedmesh.models import get_model

    room = load_shipped("example3.json")
    run = get_model("rdue").build(room, triangulate(room),
                                  {"speed_law": "table", "speed_table": TABLE})
    top = 0.0
    while not run.done and run.t < 300:
        run.step()
        top = max(top, float(run.state.Q[:, 0].max()))
    assert 3.0 < top <= 1.05 * 5.6
