"""Mesh options reach Triangle exactly, and oversized meshes are refused before they are
built."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pedmesh import Exit, MeshError, Room
from pedmesh.cli import main
from pedmesh.mesh.triangulate import _fixed, estimate_cells, triangulate

SQUARE = Room([(0, 0), (0.1, 0), (0.1, 0.1), (0, 0.1)], exits=[Exit("e", [(0.1, 0), (0.1, 0.1)])])


@pytest.mark.parametrize("x", [1e-6, 2.5e-7, 0.5, 123456.0, 1 / 3, 30.0, 0.0])
def test_fixed_notation_is_exact_and_plain(x):
    s = _fixed(x)
    assert "e" not in s.lower() and float(s) == x


@pytest.mark.parametrize("max_area", [1e-6, 5e-5])
def test_area_bounds_in_e_notation_range_are_obeyed(max_area):
    """Every triangle is within the bound, so area / max_area is a lower bound of the count;
    Triangle's quality mesh makes about 1.6 times that (at most 2.2 here)."""
    mesh = triangulate(SQUARE, max_area=max_area)
    assert mesh.areas.max() <= max_area * (1 + 1e-9)
    assert 1.0 <= mesh.n_triangles * max_area / SQUARE.area <= 2.2


def test_every_switch_string_reaches_triangle_in_plain_notation(monkeypatch):
    """The initial call and the graded refinements (per-triangle areas) get the angle and
    the area as plain decimals that parse back to the very numbers asked for."""
    import re

    import triangle

    seen = []
    real = triangle.triangulate

    def spy(tri, opts=""):
        seen.append(opts)
        return real(tri, opts)

    monkeypatch.setattr(triangle, "triangulate", spy)
    angle, area = 25.000000000000004, 3e-5
    mesh = triangulate(SQUARE, max_area=area, min_angle=angle, exit_size=0.002)
    assert len(seen) >= 2 and seen[0].startswith("pq") and seen[1].startswith("rpq")
    for opts in seen:
        assert "e" not in opts.lower(), opts
        assert float(re.search(r"q([0-9.]+)", opts).group(1)) == angle
    assert float(re.fullmatch(r"pq[0-9.]+a([0-9.]+)", seen[0]).group(1)) == area
    assert all(re.fullmatch(r"rpq[0-9.]+a", o) for o in seen[1:])
    assert mesh.areas.max() <= area * (1 + 1e-9)


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
    n = triangulate(room, max_area=max_area, feature_area=None).n_triangles
    assert 0.9 <= n / estimate_cells(room, max_area) <= 1.1


@pytest.mark.parametrize("geometry", ["example2.json", "pillar_hall.json", "l_shaped.json",
                                      "corridor_bottleneck.json"])
def test_default_graded_mesh_and_its_estimate(load_shipped, geometry):
    """The default mesh: 0.3 m^2 at exits, corners and walls, up to 2 m^2 in the open; the
    size estimate made before meshing holds for it too."""
    from pedmesh.mesh.triangulate import size_fields

    room = load_shipped(geometry)
    mesh = triangulate(room)
    uniform = triangulate(room, max_area=0.5, feature_area=None)  # (the default before)
    est = estimate_cells(room, 2.0, size_fields(room))
    assert 0.85 <= mesh.n_triangles / est <= 1.15
    assert mesh.n_triangles < uniform.n_triangles
    assert mesh.min_angle >= 29.9
    # small triangles at the exits, large ones far from every feature
    ex = mesh.edge_triangles[mesh.exit_edges(), 0]
    assert mesh.areas[ex].max() <= 0.4  # (the target is met at the centroid, ~0.3 m in)
    if geometry == "example2.json":
        assert mesh.areas.max() > 1.5 and mesh.n_triangles < 0.4 * uniform.n_triangles


def test_graded_estimate_is_close(load_shipped):
    room = load_shipped("example2.json")
    from pedmesh.mesh.triangulate import exit_size_field

    n = triangulate(room, max_area=2.0, feature_area=None, exit_size=0.3).n_triangles
    est = estimate_cells(room, 2.0, [exit_size_field(room, 0.3)])
    assert 0.85 <= n / est <= 1.15


def test_oversized_mesh_is_refused_before_it_is_built(load_shipped, geometries_dir, capsys):
    room = load_shipped("example2.json")
    with pytest.raises(MeshError, match=r"about [\d,]+ triangles, more than the limit of 1,000"):
        triangulate(room, max_area=0.5, max_cells=1000)
    assert triangulate(room, max_area=20.0, feature_area=None, max_cells=1000).n_triangles < 1000
    assert triangulate(room, max_area=5.0, max_cells=math.inf).n_triangles > 1000  # no limit
    with pytest.raises(MeshError, match="more than the limit of 1,000"):  # graded: counted
        triangulate(room, max_area=20.0, max_cells=1000)
    status = main(["mesh", str(geometries_dir / "example2.json"), "--max-area", "1e-4"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and "--max-cells" in err[0]
    status = main(["mesh", str(geometries_dir / "l_shaped.json"), "--max-area", "0.5",
                   "--max-cells", "0"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and "max_cells must be a positive" in err[0]


def test_default_limit_and_bad_limits():
    """None means the default limit in triangulate(); the check comes before any meshing
    (1.6e7 triangles would take minutes)."""
    with pytest.raises(MeshError, match=r"limit of 2,000,000.*--max-cells N"):
        triangulate(SQUARE, max_area=1e-9)
    with pytest.raises(MeshError, match=r"limit of 2,000,000"):
        triangulate(SQUARE, max_area=1e-9, max_cells=None)
    for bad in (0, -5, float("nan"), True, "100"):
        with pytest.raises(MeshError, match="max_cells must be a positive number"):
            triangulate(SQUARE, max_cells=bad)
    assert triangulate(SQUARE, max_area=1e-4, max_cells=np.int64(1000)).n_triangles < 1000
    with pytest.raises(MeshError, match=r"more than the limit of 100;"):
        triangulate(SQUARE, max_area=1e-4, max_cells=np.int64(100))


@pytest.mark.parametrize("kw", [dict(exit_size=float("inf")), dict(exit_size=-1.0),
                                dict(exit_size=0.01, size_growth=float("nan")),
                                dict(max_area=float("inf")), dict(min_angle=float("nan"))])
def test_non_finite_mesh_options_are_refused(kw):
    with pytest.raises(MeshError):
        triangulate(SQUARE, **kw)


def test_mesher_does_not_import_the_room_model():
    """The tolerance the mesher shares with the room model lives in its own module; room.py
    re-exports it for old imports."""
    import ast
    import importlib
    from pathlib import Path

    room_mod = importlib.import_module("pedmesh.geometry.room")
    tri_mod = importlib.import_module("pedmesh.mesh.triangulate")  # not the function
    from pedmesh.geometry import tolerances

    tree = ast.parse(Path(tri_mod.__file__).read_text(encoding="utf-8"))
    names = [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    names += [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    assert not [n for n in names if n.endswith("room") or n in ("..geometry", "geometry")]
    assert "geometry.tolerances" in names
    assert room_mod.EXIT_TOLERANCE is tolerances.EXIT_TOLERANCE == 1e-6
