"""Table-driven bad input: each case raises the right pedmesh error naming the element,
and the CLI prints exactly one line on stderr and exits with status 2."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pedmesh import (
    GeometryError,
    PedmeshError,
    RoomFileError,
    UnsupportedFormatError,
    load_room,
)
from pedmesh.cli import main

BOX = [[0, 0], [10, 0], [10, 5], [0, 5]]
EXIT = {"name": "door", "polyline": [[10, 2], [10, 3]]}


def room(**kw):
    d = {"outline": BOX, "exits": [EXIT]}
    d.update(kw)
    return json.dumps(d)


def sq(x0, y0, x1, y1):
    return [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]


def write_dxf(path: Path, layers: dict[str, list]) -> None:
    import ezdxf

    doc = ezdxf.new()
    msp = doc.modelspace()
    for layer, pts in layers.items():
        msp.add_lwpolyline(pts, close=True, dxfattribs={"layer": layer})
    doc.saveas(path)


# (id, suffix, content (str, or callable(path) that writes the file), error class, message part)
CASES = [
    ("self-intersecting outline", ".json",
     json.dumps({"outline": [[0, 0], [10, 5], [10, 0], [0, 5]]}),
     GeometryError, "room outline: the outline intersects itself"),
    ("obstacle crossing a wall", ".json",
     room(obstacles=[{"name": "pillar-1", "polygon": sq(8, 1, 12, 2)}]),
     GeometryError, "obstacle 'pillar-1' crosses the room outline"),
    ("obstacle outside the room", ".json",
     room(obstacles=[{"name": "far", "polygon": sq(20, 1, 22, 2)}]),
     GeometryError, "obstacle 'far' lies outside the room outline"),
    ("obstacle touching the outline", ".json",
     room(obstacles=[{"name": "nook", "polygon": sq(0, 1, 2, 2)}]),
     GeometryError, "obstacle 'nook' touches the room outline"),
    ("overlapping obstacles", ".json",
     room(obstacles=[{"name": "pillar-2", "polygon": sq(2, 1, 4, 3)},
                     {"name": "pillar-3", "polygon": sq(3, 2, 5, 4)}]),
     GeometryError, "obstacle 'pillar-2' overlaps obstacle 'pillar-3'"),
    ("exit off the boundary", ".json",
     room(exits=[{"name": "door", "polyline": [[9, 2], [9, 3]]}]),
     GeometryError, "exit 'door' does not lie on the room outline"),
    ("exit cutting a corner", ".json",
     room(exits=[{"name": "diag", "polyline": [[9, 0], [10, 1]]}]),
     GeometryError, "exit 'diag' does not lie on"),
    ("zero-length exit", ".json",
     room(exits=[{"name": "door", "polyline": [[10, 2], [10, 2]]}]),
     GeometryError, "exit 'door': all points coincide, so it has zero length"),
    ("overlapping exits", ".json",
     room(exits=[{"name": "a", "polyline": [[10, 1], [10, 3]]},
                 {"name": "b", "polyline": [[10, 2], [10, 4]]}]),
     GeometryError, "exit 'a' overlaps exit 'b'"),
    ("NaN coordinate", ".json",
     '{"outline": [[0, 0], [10, 0], [10, NaN], [0, 5]]}',
     GeometryError, "room outline: point 2 has a non-finite coordinate nan"),
    ("string coordinate", ".json",
     room(obstacles=[{"name": "p", "polygon": [[2, 1], ["3", 1], [3, 2]]}]),
     GeometryError, "obstacle 'p': point 1 has a non-numeric coordinate '3'"),
    ("empty file", ".json", "", RoomFileError, "the file is empty"),
    ("truncated JSON", ".json", room()[:-7], RoomFileError, "invalid JSON at line 1"),
    ("unknown top-level key", ".json",
     json.dumps({"outline": BOX, "exitz": []}), RoomFileError, "unknown key 'exitz'"),
    ("unknown element key", ".json",
     room(exits=[{"name": "door", "polylin": [[10, 2], [10, 3]]}]),
     RoomFileError, "exits[0] ('door'): unknown key 'polylin'"),
    ("missing outline", ".json", json.dumps({"exits": [EXIT]}),
     RoomFileError, "missing required key 'outline'"),
    ("outline with two points", ".json", json.dumps({"outline": [[0, 0], [1, 1]]}),
     GeometryError, "room outline: a polygon needs at least 3 distinct points"),
    ("top level not an object", ".json", "[1, 2, 3]",
     RoomFileError, "the top level must be a JSON object"),
    ("feet instead of metres", ".json", json.dumps({"outline": BOX, "units": "ft"}),
     RoomFileError, "'units' must be 'm'"),
    ("start area inside an obstacle", ".json",
     room(obstacles=[{"name": "pillar", "polygon": sq(2, 1, 5, 4)}],
          start_areas=[{"name": "crowd", "polygon": sq(3, 2, 4, 3), "count": 4}]),
     GeometryError, "start area 'crowd' overlaps obstacle 'pillar'"),
    ("start area outside the room", ".json",
     room(start_areas=[{"name": "crowd", "polygon": sq(8, 1, 12, 2), "spacing": 0.5}]),
     GeometryError, "start area 'crowd' is not inside the room"),
    ("start area with two parameters", ".json",
     room(start_areas=[{"name": "crowd", "polygon": sq(1, 1, 2, 2), "count": 4, "spacing": 1}]),
     GeometryError, "start area 'crowd': give exactly one of 'count', 'spacing' or 'density'"),
    ("negative density", ".json",
     room(start_areas=[{"name": "crowd", "polygon": sq(1, 1, 2, 2), "density": -1}]),
     GeometryError, "start area 'crowd': density must be a positive finite number"),
    ("duplicate exit names", ".json",
     room(exits=[EXIT, {"name": "door", "polyline": [[10, 3.5], [10, 4]]}]),
     GeometryError, "exit name 'door' is used more than once"),
    ("unknown GeoJSON role", ".geojson",
     json.dumps({"type": "FeatureCollection", "features": [
         {"type": "Feature", "properties": {"role": "door"},
          "geometry": {"type": "LineString", "coordinates": [[0, 0], [1, 0]]}}]}),
     RoomFileError, "feature 0: unknown role 'door'"),
    ("GeoJSON without a room", ".geojson",
     json.dumps({"type": "FeatureCollection", "features": []}),
     RoomFileError, "no feature with role 'room'"),
    ("GeoJSON exit as polygon", ".geojson",
     json.dumps({"type": "FeatureCollection", "features": [
         {"type": "Feature", "properties": {"role": "exit", "name": "e"},
          "geometry": {"type": "Polygon", "coordinates": [[[0, 0], [1, 0], [1, 1], [0, 0]]]}}]}),
     RoomFileError, "feature 0 (exit 'e'): geometry must be a LineString"),
    ("unsupported suffix", ".txt", room(),
     UnsupportedFormatError, "unsupported geometry file suffix '.txt'"),
    ("DXF with no room layer", ".dxf",
     lambda p: write_dxf(p, {"obstacle": sq(2, 1, 3, 2)}),
     RoomFileError, "no closed polyline on a 'room' layer"),
    ("not a DXF file", ".dxf", "this is not a drawing\n",
     RoomFileError, "not a valid DXF file"),
    ("DXF obstacle crossing the wall", ".dxf",
     lambda p: write_dxf(p, {"room": sq(0, 0, 10, 5), "obstacle-col": sq(9, 1, 11, 2)}),
     GeometryError, "obstacle 'col' crosses the room outline"),
]


def _make(tmp_path: Path, case) -> Path:
    name, suffix, content = case[0], case[1], case[2]
    path = tmp_path / (name.replace(" ", "_") + suffix)
    if callable(content):
        content(path)
    else:
        path.write_text(content)
    return path


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_bad_input_raises_named_error(case, tmp_path):
    path = _make(tmp_path, case)
    _, _, _, cls, message = case
    with pytest.raises(cls) as info:
        load_room(path)
    assert type(info.value) is cls
    assert message in str(info.value)
    assert str(path) in str(info.value)  # the file is named too


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_cli_prints_one_line_and_exits_2(case, tmp_path, capsys):
    path = _make(tmp_path, case)
    status = main(["mesh", str(path)])
    out, err = capsys.readouterr()
    assert status == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("pedmesh: error: ")
    assert case[4] in lines[0]
    assert "Traceback" not in err


def test_missing_file(tmp_path, capsys):
    with pytest.raises(RoomFileError, match="no such file"):
        load_room(tmp_path / "nope.json")
    assert main(["mesh", str(tmp_path / "nope.json")]) == 2


def test_debug_shows_the_exception(tmp_path):
    p = tmp_path / "bad.json"
    p.write_text("{")
    with pytest.raises(PedmeshError):
        main(["--debug", "mesh", str(p)])


def test_at_least_fifteen_cases():
    assert len(CASES) >= 15
