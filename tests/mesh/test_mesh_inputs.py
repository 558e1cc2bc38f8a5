"""Mesh options reach Triangle exactly, and oversized meshes are refused before they are
built."""

from __future__ import annotations

import math

import pytest

from pedmesh import Exit, MeshError, Room
from pedmesh.cli import main
from pedmesh.mesh.triangulate import _fixed, estimate_cells, triangulate

SQUARE = Room([(0, 0), (0.1, 0), (0.1, 0.1), (0, 0.1)], exits=[Exit("e", [(0.1, 0), (0.1, 0.1)])])


@pytest.mark.parametrize("x", [1e-6, 2.5e-7, 0.5, 123456.0, 1 / 3, 30.0, 0.0])
def test_fixed_notation_is_exact_and_plain(x):
    s = _fixed(x)
    assert "e" not in s.lower() and float(s) == x


def test_tiny_max_area_gives_the_triangles_it_asks_for():
    """A 0.1 x 0.1 m room at max_area 1e-6 m^2 needs at least area / max_area = 10,000
    triangles (Triangle read 'a1e-06' as a much larger area and made 795)."""
    mesh = triangulate(SQUARE, max_area=1e-6)
    assert mesh.areas.max() <= 1e-6 * (1 + 1e-9)
    assert mesh.n_triangles >= 0.01 / 1e-6
    est = estimate_cells(SQUARE, 1e-6)
    assert 0.7 * est <= mesh.n_triangles <= 1.3 * est


@pytest.mark.parametrize("geometry", ["example2.json", "pillar_hall.json", "l_shaped.json"])
@pytest.mark.parametrize("max_area", [2.0, 0.5, 0.1])
def test_cell_estimate_is_close(load_shipped, geometry, max_area):
    room = load_shipped(geometry)
    n = room.mesh(max_area=max_area).n_triangles
    assert 0.9 <= n / estimate_cells(room, max_area) <= 1.1


def test_graded_estimate_is_close(load_shipped):
    room = load_shipped("example2.json")
    from pedmesh.mesh.triangulate import exit_size_field

    n = room.mesh(max_area=2.0, exit_size=0.3).n_triangles
    est = estimate_cells(room, 2.0, [exit_size_field(room, 0.3)])
    assert 0.85 <= n / est <= 1.15


def test_oversized_mesh_is_refused_before_it_is_built(load_shipped, geometries_dir, capsys):
    room = load_shipped("example2.json")
    with pytest.raises(MeshError, match=r"about [\d,]+ triangles, more than the limit of 1,000"):
        room.mesh(max_area=0.5, max_cells=1000)
    assert room.mesh(max_area=20.0, max_cells=1000).n_triangles < 1000
    assert room.mesh(max_area=5.0, max_cells=math.inf).n_triangles > 1000  # no limit
    status = main(["mesh", str(geometries_dir / "example2.json"), "--max-area", "1e-4"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and "--max-cells" in err[0]
    status = main(["mesh", str(geometries_dir / "l_shaped.json"), "--max-area", "0.5",
                   "--max-cells", "0"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and "max_cells must be a positive" in err[0]
