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
    ("rdue", "rho_eps=-1", "parameter 'rho_eps' must be >= 0"),
    ("pw", "limiter=0.5", "parameter 'limiter' must be 0 or 1"),
    ("pw", "cfl=inf", "parameter 'cfl' must be a finite number"),
    ("pw", "c0=-1", "parameter 'c0' must be >= 0"),
    ("rdue", "U_f=-inf", "parameter 'U_f' must be a finite number"),
    ("sfm", "dt=inf", "parameter 'dt' must be a finite number"),
    ("sfm", "A=nan", "parameter 'A' must be a finite number"),
    ("sfm", "tau=-0.5", "parameter 'tau' must be positive"),
    ("mac1", "output_interval=0", "parameter 'output_interval' must be positive"),
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
    ("pw", "rho_eps=-1", "parameter 'rho_eps' must be >= 0"),
    ("pw", "eps_hat=-0.1", "parameter 'eps_hat' must be positive"),
    ("pw", "cfl=1.5", "parameter 'cfl' must be in (0, 1]"),
    ("pw", "u_max=-1", "parameter 'u_max' must be positive"),
    ("pw", "tau=0", "parameter 'tau' must be positive"),
    ("pw", "limiter=yes", "parameter 'limiter' must be 0 or 1"),
    ("pw", "route_every_step=2", "parameter 'route_every_step' must be 0 or 1"),
    ("pw", "sample_interval=-0.1", "parameter 'sample_interval' must be positive"),
    ("pw", "empty_below=inf", "parameter 'empty_below' must be a finite number"),
    ("eos", "A=-1", "parameter 'A' must be positive"),
    ("eos", "r=nan", "parameter 'r' must be a finite number"),
    ("mac1", "walls=0.5", "parameter 'walls' must be 0 or 1"),
    ("mac1", "friction=-1", "parameter 'friction' must be 0 or 1"),
    ("sfm", "dt=inf", "parameter 'dt' must be a finite number"),
    ("sfm", "dt=-0.01", "parameter 'dt' must be positive"),
    ("sfm", "A=nan", "parameter 'A' must be a finite number"),
    ("sfm", "m=0", "parameter 'm' must be positive"),
    ("sfm", "density_stages=2", "parameter 'density_stages' must be 1 or 3"),
    ("sfm", "route_interval=-1", "parameter 'route_interval' must be >= 0"),
    ("sfm", "overlap_tolerance=-0.01", "parameter 'overlap_tolerance' must be >= 0"),
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
