"""A building's surface mesh: levels at their heights, stairs sloped, stitched along the
stair edges, written to VTK as one 3-D dataset."""

from __future__ import annotations

import json
import math

import numpy as np

import pedmesh
from pedmesh.cli import main
from pedmesh.mesh.building import triangulate_building

from building_data import TWO  # (tests/building_data.py)

def test_the_surface_is_stitched_and_true_in_3d(tmp_path):
    p = tmp_path / "b.json"
    p.write_text(json.dumps(TWO))
    b = pedmesh.load_room(p)
    m = triangulate_building(b, max_area=1.0)
    assert math.isclose(m.area, b.area, rel_tol=1e-12)  # 394 m^2 on the surface
    assert m.edge_triangle_counts.max() == 2
    assert np.sum(m.edge_triangle_counts == 1) == len(m.segments)  # the hinges are interior
    ground, first = m.piece_index("ground"), m.piece_index("first")
    z = m.points[:, 2]
    assert set(np.unique(z[m.triangles[m.piece == ground]])) == {0.0}
    assert set(np.unique(z[m.triangles[m.piece == first]])) == {3.0}
    stair = m.pieces[m.piece_index("stair")]
    # the stair's chart is isometric: areas and edge lengths as in 3-D
    assert math.isclose(stair.mesh.areas.sum(), m.areas[stair.triangles].sum(), rel_tol=1e-12)
    uv = stair.to_chart(m.points[stair.vertices])
    assert np.allclose(uv, stair.mesh.points, atol=1e-9)
    assert np.allclose(stair.to_3d(stair.mesh.points), m.points[stair.vertices], atol=1e-9)
    # every triangle of the stair is inclined at the stair's slope
    n = m.normals[stair.triangles]
    assert np.allclose(np.degrees(np.arccos(n[:, 2])), b.slope(b.stairs[0]))


def test_pedmesh_mesh_writes_the_building_in_3d(tmp_path, capsys):
    import pyvista as pv

    p = tmp_path / "b.json"
    p.write_text(json.dumps(TWO))
    out = tmp_path / "b.vtu"
    assert main(["mesh", str(p), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "building 'two-storey'" in text and "slope 36.9 deg" in text
    g = pv.read(out)
    assert g.bounds[4] == 0.0 and g.bounds[5] == 3.0
    assert set(g.cell_data) >= {"piece", "stair", "area"}
    assert math.isclose(float(np.sum(g.cell_data["area"])), 394.0, rel_tol=1e-12)


def test_models_that_cannot_run_a_building_say_so(tmp_path, capsys):
    p = tmp_path / "b.json"
    p.write_text(json.dumps(TWO))
    # models that do not run on buildings yet say so in one line
    assert main(["run", str(p), "--model", "mac1", "--out", str(tmp_path / "m"), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "does not run on buildings" in err[0]


def test_the_shipped_office_building(geometries_dir, tmp_path, capsys):
    """geometries/office.json: five storeys, two stairwells, a door on each side; its mesh,
    route and 3-D model."""
    import trimesh

    b = pedmesh.load_room(geometries_dir / "office.json")
    assert len(b.levels) == 5 and len(b.stairs) == 8 and b.exit_names == ("west-door",
                                                                         "east-door")
    assert main(["route", str(geometries_dir / "office.json"), "-o",
                 str(tmp_path / "r.vtu")]) == 0
    assert "distance to exit on the surface" in capsys.readouterr().out
    assert main(["export", str(geometries_dir / "office.json"), "-o",
                 str(tmp_path / "o.glb")]) == 0
    scene = trimesh.load(tmp_path / "o.glb")
    names = set(scene.geometry)
    assert {"ground/floor", "fourth/floor", "west-0-1/stairs", "east-3-4/stairs"} <= names
    # glTF is y-up: the top floor's walls reach 14 m + 2.5 m
    assert math.isclose(scene.bounds[1][1], 16.5, rel_tol=1e-6)


def test_obstacles_are_numbered_once_each(tmp_path):
    """A level's pillar is one obstacle of the surface and of the atlas (not one per side)."""
    from pedmesh.mesh.atlas import build_atlas
    from pedmesh.mesh.triangle_mesh import BoundaryKind

    data = json.loads(json.dumps(TWO))
    data["levels"][0]["obstacles"] = [{"name": "pillar",
                                       "polygon": [[4, 4], [5, 4], [5, 5], [4, 5]]}]
    p = tmp_path / "b.json"
    p.write_text(json.dumps(data))
    s = triangulate_building(pedmesh.load_room(p))
    assert s.obstacle_names == ("ground/pillar",)
    assert set(s.segment_owner[s.segment_kind == BoundaryKind.OBSTACLE]) == {0}
    g = build_atlas(s).glued
    assert g.obstacle_names == ("ground/pillar",)
    assert set(g.edge_owner[g.edge_kind == BoundaryKind.OBSTACLE]) == {0}


def test_a_buildings_route_mesh_is_reused_for_another_crowd(tmp_path):
    """The route mesh of a building is kept like a room's (a fit or an ensemble builds it
    many times): the same levels and stairs with another crowd get the same mesh, carrying
    their own building; a stair moved gets a mesh of its own."""
    from pedmesh.mesh.building import building_fingerprint
    from pedmesh.mesh.route_mesh import route_mesh

    def load(spec: dict, name: str):
        p = tmp_path / f"{name}.json"
        p.write_text(json.dumps(spec))
        return pedmesh.load_room(p)

    b1 = load(TWO, "a")
    crowd = json.loads(json.dumps(TWO))
    crowd["levels"][0]["start_areas"][0]["spacing"] = 0.7  # another crowd, same walls
    b2 = load(crowd, "b")
    moved = json.loads(json.dumps(TWO))
    moved["stairs"][0]["top"]["edge"] = [[12, 8.5], [12, 10]]
    moved["levels"][1]["outline"] = [[0, 0], [20, 0], [20, 10], [12, 10], [12, 8.5],
                                     [8, 8.5], [8, 10], [0, 10]]
    moved["stairs"][0]["polygon"] = [[8, 8.5], [12, 8.5], [12, 10], [8, 10]]
    moved["stairs"][0]["bottom"]["edge"] = [[8, 8.5], [8, 10]]
    b3 = load(moved, "c")
    assert building_fingerprint(b1) == building_fingerprint(b2) != building_fingerprint(b3)
    m1 = route_mesh(b1, resolution=0.2, kernel=2.0)
    m2 = route_mesh(b2, resolution=0.2, kernel=2.0)
    assert m1.building is b1 and m2.building is b2
    assert m2.points is m1.points  # (not meshed again)
    m3 = route_mesh(b3, resolution=0.2, kernel=2.0)
    assert m3.building is b3
    assert math.isclose(m1.area, b1.area, rel_tol=1e-12)
    assert math.isclose(m3.area, b3.area, rel_tol=1e-12) and m3.area < m1.area - 0.4
