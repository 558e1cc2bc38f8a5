"""The command line, called through main([...])."""

from __future__ import annotations

import subprocess
import sys

import meshio
import numpy as np
import pytest

from pedmesh.cli import main


def test_mesh_command_summary_and_vtu(geometries_dir, tmp_path, capsys):
    out = tmp_path / "sub" / "ex3.vtu"
    assert main(["mesh", str(geometries_dir / "example3.json"), "--max-area", "2", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    for part in ("vertices", "triangles", "smallest", "exit-south 10.000 m", "exit-north 10.000 m",
                 "4800.000 m^2", "2400 in 1 start area"):
        assert part in text
    m = meshio.read(out)
    assert set(np.unique(m.cell_data_dict["boundary_kind"]["line"])) == {1, 2, 3}


def test_mesh_rejects_non_vtu_output(geometries_dir, tmp_path, capsys):
    assert main(["mesh", str(geometries_dir / "l_shaped.json"), "-o", str(tmp_path / "m.txt")]) == 2
    assert "use a .vtu suffix" in capsys.readouterr().err


def test_bad_mesh_option_is_one_line(geometries_dir, capsys):
    assert main(["mesh", str(geometries_dir / "l_shaped.json"), "--max-area", "-3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "max_area" in err[0]


@pytest.mark.parametrize("args", [["--help"], ["mesh", "--help"]])
def test_help(args, capsys):
    with pytest.raises(SystemExit) as info:
        main(args)
    assert info.value.code == 0
    assert "usage: pedmesh" in capsys.readouterr().out


def test_console_script_runs(geometries_dir):
    r = subprocess.run([sys.executable, "-m", "pedmesh", "mesh", str(geometries_dir / "nope.json")],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.strip() == f"pedmesh: error: {geometries_dir / 'nope.json'}: no such file"


def test_route_command(geometries_dir, tmp_path, capsys):
    out = tmp_path / "route.vtu"
    assert main(["route", str(geometries_dir / "example3.json"), "--max-area", "2", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "solve" in text and "distance to exit" in text
    m = meshio.read(out)
    assert m.point_data["phi"].min() == 0.0
    assert 100 < m.point_data["phi"].max() < 102  # far corner (0, 0 or 50): about 100.5 m
    d = m.point_data["direction"]
    np.testing.assert_allclose(np.hypot(d[:, 0], d[:, 1]), 1.0, atol=1e-12)


def test_route_unknown_exit(geometries_dir, tmp_path, capsys):
    assert main(["route", str(geometries_dir / "example3.json"), "--exits", "exit-west",
                 "-o", str(tmp_path / "r.vtu")]) == 2
    assert "unknown exit 'exit-west'" in capsys.readouterr().err
