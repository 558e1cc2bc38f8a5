"""Every numeric parameter is checked: non-finite, out-of-range and non-integral values
give one line and exit status 2, before anything is simulated."""

from __future__ import annotations

import pytest

from pedmesh.cli import main


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
