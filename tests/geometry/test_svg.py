"""SVG floor plans: roles from ids, labels and groups; units, the y axis, transforms and
curves; clear errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pedmesh import RoomFileError, load_room
from pedmesh.mesh import triangulate

SVG = """<svg xmlns="http://www.w3.org/2000/svg"
     xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape" {root}>
{body}
</svg>
"""


def _write(tmp_path, body: str, root: str = "", name: str = "plan.svg"):
    p = tmp_path / name
    p.write_text(SVG.format(root=root, body=body), encoding="utf-8")
    return p


def test_shipped_foyer(geometries_dir):
    room = load_room(geometries_dir / "foyer.svg")
    assert room.name == "foyer"
    assert sorted(room.outline) == sorted([(0, 0), (30, 0), (30, 20), (0, 20)])
    exits = {e.name: sorted(e.polyline) for e in room.exits}
    # drawn in cm; the north door is at the top of the picture (SVG y = 0): y = 20 m here
    assert exits == {"east": [(30.0, 8.0), (30.0, 12.0)], "north": [(22.0, 20.0), (26.0, 20.0)]}
    obstacles = {o.name: o.shape for o in room.obstacles}
    assert set(obstacles) == {"pillar-round", "obstacle", "counter"}  # rect12: the group's name
    assert obstacles["pillar-round"].area == pytest.approx(math.pi, rel=0.015)
    assert obstacles["pillar-round"].centroid.coords[0] == pytest.approx((15.0, 13.0), abs=1e-3)
    assert obstacles["counter"].area == pytest.approx(10 + math.pi / 2, rel=0.015)
    assert len(obstacles["pillar-round"].exterior.coords) < 60  # flattened to 1 cm, not 12k
    (start,) = room.start_areas
    assert start.density == 1.5 and start.shape.area == pytest.approx(80.0)
    assert [m.name for m in room.measurement_lines] == ["door"]
    mesh = triangulate(room)
    assert mesh.n_triangles < 5000 and list(mesh.exit_names) == ["east", "north"]


def test_same_room_as_built_in_python(tmp_path):
    from pedmesh import Exit, Obstacle, Room, StartArea

    p = _write(tmp_path, """
      <rect id="room" x="0" y="0" width="12" height="8"/>
      <rect id="obstacle-box" x="5" y="3" width="2" height="2"/>
      <line id="exit" x1="12" y1="2" x2="12" y2="4"/>
      <rect id="start" x="1" y="1" width="3" height="6" data-count="20"/>""")
    got = load_room(p)
    # the same room with y mirrored about the top edge (y = 8 in the drawing)
    want = Room([(0, 0), (12, 0), (12, 8), (0, 8)],
                obstacles=[Obstacle("box", [(5, 3), (7, 3), (7, 5), (5, 5)])],
                exits=[Exit("exit", [(12, 4), (12, 6)])],
                start_areas=[StartArea("start", [(1, 1), (4, 1), (4, 7), (1, 7)], count=20)])
    assert got.walkable.symmetric_difference(want.walkable).area < 1e-9
    assert sorted(got.exits[0].polyline) == sorted(want.exits[0].polyline)
    np.testing.assert_allclose(np.sort(got.initial_positions(), axis=0),
                               np.sort(want.initial_positions(), axis=0))


def test_group_transforms_and_layers(tmp_path):
    p = _write(tmp_path, """
      <g inkscape:label="walls" transform="translate(10, 0)">
        <g id="room"><rect x="0" y="0" width="10" height="10"/></g>
      </g>
      <g transform="scale(2)">
        <circle id="obstacle-p" cx="7.5" cy="2.5" r="0.5"/>
        <line id="exit-e" x1="10" y1="1" x2="10" y2="2"/>
      </g>
      <rect id="ignored-decoration" x="0" y="0" width="1" height="1"/>""")
    room = load_room(p)
    xs = [x for x, _ in room.outline]
    assert min(xs) == 10.0 and max(xs) == 20.0
    (ob,) = room.obstacles
    assert ob.shape.centroid.coords[0] == pytest.approx((15.0, 5.0), abs=1e-3)
    assert ob.shape.area == pytest.approx(math.pi, rel=0.02)
    assert sorted(room.exits[0].polyline) == [(20.0, 6.0), (20.0, 8.0)]


@pytest.mark.parametrize(("body", "root", "message"), [
    ('<rect id="obstacle" x="0" y="0" width="1" height="1"/>', "", "no element with id"),
    ('<rect id="room" x="0" y="0" width="9" height="9"/>'
     '<polyline id="obstacle-open" points="1,1 2,1 2,2"/>', "", "must be a closed shape"),
    ('<rect id="room" x="0" y="0" width="9" height="9"/>', 'data-pedmesh-scale="-1"',
     "data-pedmesh-scale"),
    ('<rect id="room" x="0" y="0" width="9" height="9"/>'
     '<rect id="start" x="1" y="1" width="2" height="2" data-density="many"/>', "",
     "data-density='many' is not a number"),
    ('<rect id="room" x="0" y="0" width="9" height="9"/>'
     '<ellipse id="obstacle-e" cx="4" cy="4" rx="1" ry="2"/>', "", "no geometry"),
    ('<rect id="room" x="0" y="0" width="9" height="9"/>'
     '<rect id="start" x="1" y="1" width="2" height="2" data-count="2.5"/>', "",
     "data-count='2.5' is not a whole number"),
    ('<rect id="room" x="0" y="0" width="9" height="9"/>'
     '<rect id="start" x="1" y="1" width="2" height="2" data-count="4" data-spacing="1"/>', "",
     "give one of data-count"),
    ('<rect id="room" x="0" y="0" width="9" height="9"/>'
     '<rect id="room-2" x="20" y="0" width="9" height="9"/>', "",
     "2 elements have the role 'room'"),
])
def test_errors_name_the_problem(tmp_path, body, root, message):
    with pytest.raises(RoomFileError, match=message):
        load_room(_write(tmp_path, body, root))


def test_not_an_svg(tmp_path):
    p = tmp_path / "x.svg"
    p.write_text("<html><body/></html>")
    with pytest.raises(RoomFileError, match="not an SVG file"):
        load_room(p)
    p.write_text("<svg")
    with pytest.raises(RoomFileError, match="not a valid SVG file"):
        load_room(p)


@pytest.mark.parametrize("element", [
    '<rect id="obstacles-a" x="3" y="3" width="1" height="1"/>',
    '<line id="exits" x1="9" y1="1" x2="9" y2="2"/>',
    '<line id="Exit1" x1="9" y1="1" x2="9" y2="2"/>',
    '<g inkscape:label="obstacle1"><rect x="3" y="3" width="1" height="1"/></g>',
    '<line inkscape:label="measurement-door" x1="5" y1="0" x2="5" y2="9"/>',
    '<rect id="rooms" x="0" y="0" width="9" height="9"/>',
])
def test_near_misses_of_a_role_are_errors(tmp_path, element):
    body = '<rect id="room" x="0" y="0" width="9" height="9"/>' + element
    with pytest.raises(RoomFileError, match=r"unknown role; the roles are room, obstacle"):
        load_room(_write(tmp_path, body))


def test_other_ids_are_ignored_and_labels_fall_back_to_ids(tmp_path):
    p = _write(tmp_path, """
      <rect id="room" x="0" y="0" width="10" height="8"/>
      <rect id="stairs" x="1" y="1" width="2" height="2"/>
      <rect id="rect12" x="1" y="1" width="2" height="2"/>
      <g inkscape:label="Layer 1" id="layer1">
        <rect inkscape:label="pillar" id="obstacle-p" x="4" y="4" width="1" height="1"/>
      </g>
      <line id="exit" x1="10" y1="1" x2="10" y2="2"/>""")
    room = load_room(p)
    assert [o.name for o in room.obstacles] == ["p"]
    assert [e.name for e in room.exits] == ["exit"]


def test_compound_room_path_holes_are_obstacles(tmp_path):
    p = _write(tmp_path, """
      <path id="room-hall" d="M 0 0 H 10 V 8 H 0 Z M 2 2 H 3 V 3 H 2 Z M 6 5 h 1 v 2 h -1 z"/>
      <line id="exit" x1="10" y1="1" x2="10" y2="2"/>""")
    room = load_room(p)
    assert room.name == "hall" and room.area == pytest.approx(80 - 1 - 2)
    holes = sorted(o.shape.bounds for o in room.obstacles)
    assert holes == [(2.0, 5.0, 3.0, 6.0), (6.0, 1.0, 7.0, 3.0)]  # y flipped about y = 8


def test_missing_svg_packages_named(geometries_dir, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "svg.path", None)  # import svg.path raises ImportError
    with pytest.raises(RoomFileError, match="needs the packages lxml and svg.path"):
        load_room(geometries_dir / "foyer.svg")
