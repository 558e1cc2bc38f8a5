"""The SFM's measured fundamental diagram (pedmesh.calibration.measure_fundamental_diagram)
and the continuum models' table law made of it (fd_speed_table, the validated preset)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from pedmesh.calibration import (FD_FPS, box_density_speed, fd_speed_table,
                                 measure_fundamental_diagram)
from pedmesh.speed import SpeedLaw


def test_box_density_and_speed_of_known_trajectories(tmp_path):
    """People walking at 0.8 m/s along x, 1 m apart in x and y, fill the box at 1 /m^2
    (whole lattice cells in it) and are measured at exactly 0.8 m/s."""
    rows = []
    pid = 0
    for y0 in np.arange(0.5, 10.0, 1.0):
        for x0 in np.arange(-5.5, 40.0, 1.0):
            for frame in range(0, 70):
                t = frame / FD_FPS
                rows.append((pid, frame, x0 + 0.8 * t, y0))
            pid += 1
    path = tmp_path / "trajectories.txt"
    np.savetxt(path, rows, fmt=["%d", "%d", "%.6f", "%.6f"], header="id frame x y")
    rho, u, n = box_density_speed(path)
    assert u == pytest.approx(0.8, rel=1e-9)
    assert rho == pytest.approx(1.0, rel=0.02)  # (a column enters as one leaves)
    assert n > 0


def test_speed_table_of_measurements():
    rows = [{"rho0": 1.0, "seed": s, "density": d, "speed": v}
            for s, d, v in ((1, 0.9, 1.30), (2, 1.1, 1.24))]
    rows += [{"rho0": 3.0, "seed": 1, "density": 2.8, "speed": 0.6},
             {"rho0": 4.0, "seed": 1, "density": 3.6, "speed": 0.62},  # (not faster: capped)
             {"rho0": 5.0, "seed": 1, "density": 4.4, "speed": 0.2},
             {"rho0": 6.0, "seed": 1, "density": math.nan, "speed": math.nan}]
    t = fd_speed_table(rows, 1.34)
    assert t[0] == (0.0, 1.0)
    assert t[1] == (1.0, round(1.27 / 1.34, 4))  # the seeds' mean
    assert t[3][1] == t[2][1]  # never faster when denser
    g = [p[1] for p in t]
    assert all(b <= a for a, b in zip(g, g[1:])) and t[-1][1] == 0.0
    # the jam point: the line through the last two points reaches 0
    (r1, g1), (r2, g2) = t[-3], t[-2]
    assert t[-1][0] == pytest.approx(r2 - g2 * (r2 - r1) / (g2 - g1), abs=1e-3)
    SpeedLaw("table", table=t)  # a valid law


def test_validated_continuum_law_is_the_sfms_measured_diagram():
    """The validated preset gives the continuum models the table that
    pedmesh.fitting.continuum_law measured with the preset's own SFM parameters, and the SFM
    walks at that table's speed now (one realisation at 2 /m^2, within 6 %)."""
    from pedmesh.presets import DATA, get_preset
    from pedmesh.models import get_model

    path = DATA / "fd_validated.json"
    if get_preset("validated").values["speed_law"].value != "table":
        pytest.skip("the validated SFM law is not a table")
    rec = json.loads(path.read_text())
    pre = get_preset("validated")
    assert pre.continuum["speed_table"].value == rec["speed_table"]
    sfm = pre.overrides(get_model("sfm").parameter_names)
    for k, v in rec["sfm_parameters"].items():
        assert sfm[k] == v, k  # measured with today's parameters
    row, = measure_fundamental_diagram("validated", seeds=1, densities=(2.0,))
    law = SpeedLaw("table", U_f=sfm["U_f"], table=rec["speed_table"])
    assert row["speed"] == pytest.approx(float(law(row["density"])), rel=0.06)
