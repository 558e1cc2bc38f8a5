"""Adding a model takes one file: this module defines a constant-velocity continuum model,
registers it once, and runs it through ``pedmesh run`` and ``pedmesh compare`` like the
built-in models. Its evacuation times are checked against the exact ones of a crowd that
walks at a constant speed to the exit, so the test fails if the model is not really run."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pedmesh.cli import main
from pedmesh.models import get_model, unregister_model
from pedmesh.models.continuum import MacroModel, register_continuum_model
from pedmesh.parameters import Parameter

NAME = "constant-velocity"


class ConstantVelocity(MacroModel):
    """rho_t + div(rho U e) = 0: everyone walks at the speed U [m/s] along the route e."""

    name = NAME
    n_vars = 1
    exit_conditions = ("transmissive",)

    def __init__(self, *, U: float = 1.0) -> None:
        self.U = float(U)

    def speed(self, rho):
        return np.full(len(rho), self.U)

    def flux(self, qL, qR, nx, ny, ex, ey):
        un = self.U * (ex * nx + ey * ny)
        F = np.where(un[:, None] >= 0.0, qL, qR) * un[:, None]  # upwind
        return F, np.abs(un)

    def wall_flux(self, q, nx, ny, ex, ey):
        return np.zeros_like(q)

    def exit_flux(self, q, nx, ny, ex, ey, kind):
        return q * np.maximum(self.U * (ex * nx + ey * ny), 0.0)[:, None]

    def velocity(self, q):
        return np.zeros((len(q), 2))

    def parameters(self) -> dict:
        return {"U": self.U}


SPEED = Parameter("U", 1.0, "m/s", "walking speed of everyone", low=0.0)


@pytest.fixture
def toy_model():
    register_continuum_model(NAME, ConstantVelocity, (SPEED,), replace=True,
                             description="everyone walks at one speed along the route")
    yield get_model(NAME)
    unregister_model(NAME)


def _corridor(tmp_path):
    """A 12 m x 3 m corridor with its exit at x = 12 m and a crowd on x in [1, 3] m: at a
    speed U the first leave after 9/U s, half after 10/U s and the last after 11/U s."""
    room = {"name": "corridor", "outline": [[0, 0], [12, 0], [12, 3], [0, 3]],
            "exits": [{"name": "east", "polyline": [[12, 0], [12, 3]]}],
            "start_areas": [{"name": "crowd", "polygon": [[1, 0.5], [3, 0.5], [3, 2.5],
                                                          [1, 2.5]], "density": 4.0}]}
    path = tmp_path / "corridor.json"
    path.write_text(json.dumps(room))
    return path


def test_a_toy_model_runs_through_pedmesh_run(tmp_path, toy_model, capsys):
    assert toy_model.scale == "continuum" and toy_model.parameter_names >= {"U", "cfl"}
    out = tmp_path / "run"
    status = main(["run", str(_corridor(tmp_path)), "--model", NAME, "--param", "U=1.25",
                   "--max-area", "0.1", "--out", str(out), "-q"])
    assert status == 0, capsys.readouterr().err
    s = json.loads((out / "summary.json").read_text())
    assert s["model"] == NAME and s["status"] == "finished"
    assert s["parameters"]["U"] == 1.25
    assert s["n_evacuated"] == pytest.approx(16.0, abs=0.5)  # 4 /m^2 on 2 m x 2 m
    # the exact times 10/U and 11/U; the scheme's numerical diffusion spreads the front
    assert s["t_evac_50"] == pytest.approx(10.0 / 1.25, rel=0.05)
    assert 9.0 / 1.25 < s["t_evac_90"] < 11.5 / 1.25


def test_a_toy_model_runs_through_pedmesh_compare(tmp_path, toy_model, capsys):
    out = tmp_path / "cmp"
    status = main(["compare", str(_corridor(tmp_path)), "--models",
                   f"{NAME}:U=1.0,{NAME}:U=2.0", "--max-area", "0.1", "--out", str(out), "-q"])
    assert status == 0, capsys.readouterr().err
    table = (out / "comparison.csv").read_text()
    assert "U1" in table and "U2" in table
    t50 = {}
    for d in out.iterdir():
        if (d / "summary.json").is_file():
            s = json.loads((d / "summary.json").read_text())
            t50[s["parameters"]["U"]] = s["t_evac_50"]
    assert t50[2.0] == pytest.approx(t50[1.0] / 2.0, rel=0.05)


def test_an_unknown_toy_parameter_is_one_line(tmp_path, toy_model, capsys):
    status = main(["run", str(_corridor(tmp_path)), "--model", NAME, "--param", "U=-1",
                   "--out", str(tmp_path / "bad"), "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and "parameter 'U' must be positive" in err[0]
