"""One site interface (issue 45): a room or a building, meshed by one function with one
set of errors, and no type tests outside pedmesh.geometry.site."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pedmesh
from pedmesh.cli import main
from pedmesh.geometry.site import is_building, site_levels
from pedmesh.mesh.site import mesh_site
from pedmesh.io import load_room
from pedmesh.mesh import triangulate, triangulate_building

ROOT = Path(__file__).resolve().parents[2]


def test_mesh_site_is_the_mesher_of_either(tmp_path):
    room = load_room(ROOT / "geometries" / "example2.json")
    a, b = mesh_site(room), triangulate(room)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.triangles, b.triangles)
    office = load_room(ROOT / "geometries" / "office.json")
    s, t = mesh_site(office, max_area=2.0), triangulate_building(office, max_area=2.0)
    assert np.array_equal(s.points, t.points) and np.array_equal(s.triangles, t.triangles)
    assert is_building(office) and not is_building(room)
    assert [(n, z) for n, z, _ in site_levels(room)] == [(None, 0.0)]
    assert [n for n, _, _ in site_levels(office)] == [lv.name for lv in office.levels]


def test_a_room_only_mesh_option_on_a_building_is_the_same_error_everywhere(tmp_path,
                                                                           capsys):
    office = ROOT / "geometries" / "office.json"
    want = "exit_size (--exit-size) is not available for buildings"
    with pytest.raises(pedmesh.PedmeshError, match=re.escape(want)):
        pedmesh.simulate(office, mesh_options={"exit_size": 0.3}, t_end=1.0)
    with pytest.raises(pedmesh.PedmeshError, match=re.escape(want)):
        pedmesh.build(office, mesh_options={"exit_size": 0.3})
    for cmd in (["mesh", str(office)], ["run", str(office), "--out", str(tmp_path / "r")],
                ["ensemble", str(office), "--members", "1", "--out", str(tmp_path / "e")]):
        assert main(cmd + ["--exit-size", "0.3"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and want in err[0], (cmd, err)


def test_no_type_sniffing_outside_the_site_module():
    out = subprocess.run(["grep", "-rnE", r"hasattr\(.*levels|isinstance\(.*Building",
                          str(ROOT / "pedmesh"), "--include=*.py"],
                         capture_output=True, text=True).stdout.splitlines()
    assert [ln for ln in out if "pedmesh/geometry/site.py" not in ln] == []
