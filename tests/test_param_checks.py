"""Every numeric parameter is checked: non-finite, out-of-range and non-integral values
give one line and exit status 2, before anything is simulated."""

from __future__ import annotations

import pytest

from pedmesh.cli import main
from pedmesh.mesh import triangulate


@pytest.mark.parametrize(("model", "param", "message"), [
    ("pw", "order=nan", "parameter 'order' must be a finite number"),
    ("pw", "order=2.5", "parameter 'order' must be 1, 2 or 3"),
    ("pw", "order=4", "parameter 'order' must be 1, 2 or 3"),
    ("rdue", "rho_eps=-1", "parameter 'rho_eps' must be in [0, 1] ped/m^2, got -1.0"),
    ("pw", "limiter=0.5", "parameter 'limiter' must be 0 or 1"),
    ("pw", "cfl=inf", "parameter 'cfl' must be a finite number"),
    ("pw", "c0=-1", "parameter 'c0' must be in [0, 10] m/s"),
    ("rdue", "U_f=-inf", "parameter 'U_f' must be a finite number"),
    ("sfm", "dt=inf", "parameter 'dt' must be a finite number"),
    ("sfm", "A=nan", "parameter 'A' must be a finite number"),
    ("sfm", "tau=-0.5", "parameter 'tau' must be in [0.05, 100] s"),
    ("mac1", "output_interval=0", "parameter 'output_interval' must be in [0.01, 1000] s"),
])
def test_bad_parameter_is_one_line(geometries_dir, tmp_path, capsys, model, param, message):
    status = main(["run", str(geometries_dir / "l_shaped.json"), "--model", model,
                   "--param", param, "--out", str(tmp_path / "run"), "-q", "--max-area", "4"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2
    assert len(err) == 1 and message in err[0], err


def test_good_integral_order_is_accepted(geometries_dir, tmp_path):
    assert main(["run", str(geometries_dir / "l_shaped.json"), "--model", "rdue", "--param",
                 "order=2", "--param", "limiter=1", "--out", str(tmp_path / "run"), "-q",
                 "--max-area", "4", "--t-end", "1"]) == 0


@pytest.fixture
def no_steps(monkeypatch):
    """Any simulation step fails the test: the checks must come before the first one."""
    from pedmesh.models.continuum.adapter import MacroRun
    from pedmesh.models.sfm.adapter import SFMRun

    def refuse(self, *a, **k):
        raise AssertionError("a step was taken")

    monkeypatch.setattr(MacroRun, "step", refuse)
    monkeypatch.setattr(SFMRun, "step", refuse)


@pytest.mark.parametrize(("model", "param", "message"), [
    ("pw", "order=nan", "parameter 'order' must be a finite number"),
    ("pw", "order=2.5", "parameter 'order' must be 1, 2 or 3"),
    ("pw", "order=0", "parameter 'order' must be 1, 2 or 3"),
    ("pw", "rho_eps=-1", "parameter 'rho_eps' must be in [0, 1]"),
    ("pw", "eps_hat=-0.1", "parameter 'eps_hat' must be in [1e-06, 1e+06]"),
    ("pw", "cfl=1.5", "parameter 'cfl' must be in [0.01, 1]"),
    ("pw", "u_max=-1", "parameter 'u_max' must be in [0.1, 100] m/s"),
    ("pw", "tau=0", "parameter 'tau' must be in [0.05, 100] s"),
    ("pw", "limiter=yes", "parameter 'limiter' must be 0 or 1"),
    ("pw", "route_every_step=2", "parameter 'route_every_step' must be 0 or 1"),
    ("pw", "sample_interval=-0.1", "parameter 'sample_interval' must be in [0.001, 1000] s"),
    ("pw", "empty_below=inf", "parameter 'empty_below' must be a finite number"),
    ("eos", "A=-1", "parameter 'A' must be in [1, 100000] N"),
    ("eos", "r=nan", "parameter 'r' must be a finite number"),
    ("mac1", "walls=0.5", "parameter 'walls' must be 0 or 1"),
    ("mac1", "friction=-1", "parameter 'friction' must be 0 or 1"),
    ("sfm", "dt=inf", "parameter 'dt' must be a finite number"),
    ("sfm", "dt=-0.01", "parameter 'dt' must be in [0.0001, 0.1] s"),
    ("sfm", "A=nan", "parameter 'A' must be a finite number"),
    ("sfm", "m=0", "parameter 'm' must be in [10, 500] kg"),
    ("sfm", "density_stages=2", "parameter 'density_stages' must be 1 or 3"),
    ("sfm", "route_interval=-1", "parameter 'route_interval' must be in [0, 1000] s"),
    ("sfm", "overlap_tolerance=-0.01", "parameter 'overlap_tolerance' must be in [0, 1] m"),
])
def test_bad_parameter_on_example3(geometries_dir, tmp_path, capsys, no_steps, model, param,
                                   message):
    status = main(["run", str(geometries_dir / "example3.json"), "--model", model,
                   "--param", param, "--out", str(tmp_path / "run"), "-q", "--max-area", "20"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2
    assert len(err) == 1 and message in err[0], err


@pytest.mark.parametrize("text", ["1", "true", "TRUE", "1.0", "0", "false"])
def test_switches_read_0_1_false_true(text):
    from pedmesh.parameters import parse_overrides as parse_param_overrides

    want = 1.0 if text.lower() in ("1", "true", "1.0") else 0.0
    assert parse_param_overrides([f"limiter={text}"]) == {"limiter": want}


def test_python_api_checks_the_same(load_shipped):
    """Values given from Python (not parsed from text) are checked as strictly."""
    from pedmesh import ParameterError
    from pedmesh.models.continuum.solver import FVOptions
    from pedmesh.models.sfm import SFMNumerics
    from pedmesh.models import get_model

    assert FVOptions(order=2.0).order == 2 and type(FVOptions(order=2.0).order) is int
    assert FVOptions(limiter=0).limiter is False
    assert type(SFMNumerics(density_stages=3.0).density_stages) is int
    for kw in (dict(order=True), dict(order=2.5), dict(order=float("nan")),
               dict(limiter=0.5), dict(limiter="1"), dict(cfl=float("nan")),
               dict(rho_eps=-1e-9), dict(eps_hat=float("inf"))):
        with pytest.raises(ParameterError):
            FVOptions(**kw)
    room = load_shipped("l_shaped.json")
    mesh = triangulate(room, max_area=4.0)
    for model, bad in (("pw", {"c0": -1.0}), ("pw", {"u_max": float("inf")}),
                       ("pw", {"U_f": "fast"}), ("pw", {"order": True}),
                       ("mac1", {"split_friction": 2}), ("eos", {"kappa": 0.0}),
                       ("rdue", {"output_interval": True})):
        with pytest.raises(ParameterError):
            get_model(model).build(room, mesh, bad)
    run = get_model("pw").build(room, mesh, {"order": 2.0, "limiter": 1.0, "u_max": None})
    assert run.fv_options.order == 2 and run.fv_options.limiter is True


# ------------------------------------------------------------------ physical ranges (issue 36)
@pytest.mark.parametrize(("model", "param", "message"), [
    ("sfm", "U_f=1e300", "parameter 'U_f' must be in [0.1, 5] m/s, got 1e+300"),
    ("eos", "U_f=1e300", "parameter 'U_f' must be in [0.1, 5] m/s, got 1e+300"),
    ("pw", "tau=1e-300", "parameter 'tau' must be in [0.05, 100] s, got 1e-300"),
    ("rdue", "beta=1e300", "parameter 'beta' must be in [0.001, 10] m^2/ped, got 1e+300"),
    ("pw", "c0=1e300", "parameter 'c0' must be in [0, 10] m/s, got 1e+300"),
    ("mac2-local", "gamma1=1e300",
     "parameter 'gamma1' must be in [0.001, 1000] N m^4/(kg ped), got 1e+300"),
    ("sfm", "k=1e300", "parameter 'k' must be in [1000, 1e+07] kg/s^2, got 1e+300"),
    ("sfm", "dt=5", "parameter 'dt' must be in [0.0001, 0.1] s, got 5.0"),
    ("sfm", "r=3", "parameter 'r' must be in [0.05, 1] m, got 3.0"),
    ("eos", "cfl=1e-9", "parameter 'cfl' must be in [0.01, 1], got 1e-09"),
    ("rdue", "threads=100000", "parameter 'threads' must be a whole number in [1, 1024], "
                               "got 100000.0"),
])
def test_absurd_but_finite_values_are_refused(geometries_dir, tmp_path, capsys, no_steps,
                                              model, param, message):
    """Issue 36, items 7 and 11: finite values no crowd has are refused before the first
    step, in one line that names the parameter and its physical range (they used to run:
    'U_f=1e300' reported 0 of 20 out with exit 0, pw 'c0=1e300' blew up with advice about
    the CFL number)."""
    status = main(["run", str(geometries_dir / "example3.json"), "--model", model,
                   "--param", param, "--out", str(tmp_path / "run"), "-q", "--max-area", "20"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2
    assert len(err) == 1 and message in err[0], err


def test_every_number_has_a_physical_range():
    """Every built-in numeric parameter declares a finite physical range within its bounds
    (or is bounded on both sides already); its ends are accepted, just outside is
    refused."""
    import math

    from pedmesh import ParameterError
    from pedmesh import parameters as P

    built_in = (P.TABLE1 + P.SPEED_LAW + P.SFM_TERMS + P.SFM_NUMERICS + P.RUN_OUTPUT
                + P.CONTINUUM + P.FV_NUMERICS)  # (not those of models registered in tests)
    assert len(built_in) == len({p.name for p in built_in})
    for p in built_in:
        if p.kind not in ("real", "integer") or p.choices:
            continue
        if p.range is None:
            assert p.low is not None and p.high is not None, p.name
            continue
        lo, hi = p.range
        assert math.isfinite(lo) and math.isfinite(hi) and lo < hi, p.name
        assert p.bounds == f"in [{lo:g}, {hi:g}]"
        for v in (lo, hi, p.default):
            if v is not None:
                p.check(v)
        for v in (hi * 1.01 + 1, lo - abs(lo) * 0.01 - 1e-9):
            with pytest.raises(ParameterError, match=f"parameter '{p.name}' must be"):
                p.check(v)
        # the bounds alone (the continuum physics classes): only the mathematics
        if p.high is None:
            p.check(hi * 10, physical=False)


def test_physics_classes_take_numerical_switches_but_runs_do_not(load_shipped):
    """The continuum physics classes (numerical objects) check the bounds only, so a test
    may switch the relaxation off with tau = 1e30; a run built from the same value is
    refused with the range, through the registry as through pedmesh.simulate."""
    import pedmesh
    from pedmesh import ParameterError
    from pedmesh.models import get_model
    from pedmesh.models.continuum.adapter import macro_model

    assert macro_model("pw", tau=1e30).tau == 1e30
    with pytest.raises(ParameterError, match="must be positive"):
        macro_model("pw", tau=0.0)  # (the bounds still hold)
    room = load_shipped("l_shaped.json")
    mesh = triangulate(room, max_area=4.0)
    with pytest.raises(ParameterError, match=r"'tau' must be in \[0.05, 100\] s"):
        get_model("pw").build(room, mesh, {"tau": 1e30})
    with pytest.raises(ParameterError, match=r"'U_f' must be in \[0.1, 5\] m/s"):
        pedmesh.simulate(room, model="sfm", params={"U_f": 1e300}, mesh=mesh)
    with pytest.raises(ParameterError, match=r"'A' must be in \[1, 100000\] N"):
        from pedmesh.models.sfm import SocialForceParams

        SocialForceParams(A=1e9)


def test_presets_lie_within_the_ranges():
    """Every value of every preset (and its continuum values) is inside its range."""
    from pedmesh import parameters as P
    from pedmesh.presets import PRESETS

    for pre in PRESETS.values():
        for k, v in {**pre.values, **pre.continuum}.items():
            P.get(k).check(v.value)
