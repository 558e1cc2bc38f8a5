"""Buildings: levels at their heights joined by stairs (pedmesh.geometry.building) and
their native JSON format, with a clear error for every malformed piece."""

from __future__ import annotations

import copy
import json
import math

import pytest

import pedmesh
from pedmesh.errors import GeometryError, PedmeshError, RoomFileError
from pedmesh.geometry import Building

from building_data import NOTCHED, TWO  # noqa: E402  (tests/building_data.py)


def _load(tmp_path, data, name="b.json"):
    p = tmp_path / name
    p.write_text(json.dumps(data))
    return pedmesh.load_room(p)


def test_a_building_file_reads_and_round_trips(tmp_path):
    b = _load(tmp_path, TWO)
    assert isinstance(b, Building)
    assert [lv.name for lv in b.levels] == ["ground", "first"]
    s = b.stairs[0]
    assert b.rise(s) == 3.0 and math.isclose(b.slope(s), math.degrees(math.atan2(3, 4)))
    # the surface area: two floors of 192 m^2 and a 4 m x 2 m stair 5 m long on its slope
    assert math.isclose(b.area, 2 * 192 + 10.0)
    assert s.speed_up == 0.5 and s.speed_down == 0.6  # the defaults
    assert b.exit_names == ("front",)
    pedmesh.save_room(b, tmp_path / "out.json")
    assert pedmesh.load_room(tmp_path / "out.json") == b


def test_single_level_files_stay_rooms(geometries_dir):
    assert isinstance(pedmesh.load_room(geometries_dir / "example2.json"), pedmesh.Room)


def _broken(change):
    data = copy.deepcopy(TWO)
    change(data)
    return data


@pytest.mark.parametrize(("change", "message"), [
    (lambda d: d["stairs"][0]["bottom"].update(level="cellar"),
     "stair 'stair': bottom: building 'two-storey' has no level 'cellar'"),
    (lambda d: d["stairs"][0]["bottom"].update(edge=[[8, 8.5], [9, 10]]),
     "its bottom edge does not lie on the stair's polygon"),
    (lambda d: d["levels"][1].update(z=6.0),
     "stair 'stair' is steeper than 45 degrees (56.3: a rise of 6 m over a run of 4 m)"),
    (lambda d: d["levels"][1].update(z=-1.0),
     "its top level 'first' is below its bottom level 'ground'"),
    (lambda d: d["stairs"][0]["top"].update(level="ground"),
     "its bottom and top are on the same level"),
    (lambda d: d["levels"][1].update(outline=[[0, 0], [20, 0], [20, 10], [12, 10], [12, 8],
                                               [10, 8], [10, 10], [0, 10]]),
     "stair 'stair' overlaps the walkable area of level 'first'"),
    (lambda d: d["levels"][1].update(exits=[{"name": "front", "polyline": [[0, 3], [0, 5]]}]),
     "exit name 'front' is used on more than one level"),
    (lambda d: d["levels"].append(dict(d["levels"][0])), "level name 'ground' is used more"),
    (lambda d: d["stairs"][0].update(speed_up=0.0), "speed_up must be a fraction"),
    (lambda d: d["levels"][1].update(outline=[[0, 0], [20, 0], [20, 10], [13, 10], [13, 8],
                                               [8, 8], [8, 10], [0, 10]]),
     "its top edge is not on the outline of level 'first'"),
    (lambda d: d["stairs"][0]["bottom"].pop("edge"), "'bottom' needs 'level' and 'edge'"),
    (lambda d: d["levels"][0].pop("z"), "levels[0]: a level needs 'z'"),
    (lambda d: d["levels"][0].update(z="low"), "'z' must be a finite height"),
    (lambda d: d.update(outline=NOTCHED), "unknown key 'outline' for a building"),
    (lambda d: d["stairs"][0].update(width=2), "unknown key 'width' for a stair"),
])
def test_malformed_buildings_get_clear_errors(tmp_path, change, message):
    with pytest.raises(PedmeshError, match=None) as err:
        _load(tmp_path, _broken(change))
    assert message in str(err.value)
    assert isinstance(err.value, (GeometryError, RoomFileError))


def test_non_parallel_edges_are_not_a_plane(tmp_path):
    data = _broken(lambda d: None)
    for lv in data["levels"]:
        lv["outline"] = [[0, 0], [20, 0], [20, 10], [13, 10], [12, 8], [8, 8], [8, 10],
                         [0, 10]]
    data["stairs"][0].update(polygon=[[8, 8], [12, 8], [13, 10], [8, 10]],
                             top={"level": "first", "edge": [[12, 8], [13, 10]]})
    with pytest.raises(GeometryError, match="bottom and top edges must be parallel"):
        _load(tmp_path, data)


def test_a_flat_connector_is_allowed(tmp_path):
    data = _broken(lambda d: d["levels"][1].update(z=0.0))
    b = _load(tmp_path, data)
    assert b.rise(b.stairs[0]) == 0.0 and b.slope(b.stairs[0]) == 0.0
    assert math.isclose(b.area, 2 * 192 + 8.0)


def test_the_cli_reports_a_bad_building_in_one_line(tmp_path, capsys):
    from pedmesh.cli import main

    p = tmp_path / "b.json"
    p.write_text(json.dumps(_broken(lambda d: d["levels"][1].update(z=6.0))))
    assert main(["mesh", str(p), "-o", str(tmp_path / "m.vtu")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "steeper than 45 degrees" in err[0]


def test_a_building_round_trips_through_dxf(tmp_path, geometries_dir):
    """DXF: each level's layers under its name ('ground.room', 'ground.exit-front', a TEXT
    'z=...' on the room layer), a stair on 'stair-NAME' with its edges on
    'stair-NAME.bottom-LEVEL' and 'stair-NAME.top-LEVEL'."""
    b = pedmesh.load_room(geometries_dir / "office.json")
    pedmesh.save_room(b, tmp_path / "office.dxf")
    back = pedmesh.load_room(tmp_path / "office.dxf")
    assert isinstance(back, Building)
    assert back.levels == b.levels and back.stairs == b.stairs


def test_dxf_building_errors_are_one_line(tmp_path):
    import ezdxf

    doc = ezdxf.new("R2010")
    msp = doc.modelspace()
    msp.add_lwpolyline([(0, 0), (10, 0), (10, 5), (0, 5)], close=True,
                       dxfattribs={"layer": "ground.room"})
    doc.saveas(tmp_path / "noz.dxf")
    with pytest.raises(RoomFileError, match="level 'ground': its room layer needs one TEXT "
                                            "'z=HEIGHT'"):
        pedmesh.load_room(tmp_path / "noz.dxf")
    msp.add_text("z=0", dxfattribs={"layer": "ground.room"})
    msp.add_lwpolyline([(10, 0), (14, 0), (14, 5), (10, 5)], close=True,
                       dxfattribs={"layer": "stair-s"})
    doc.saveas(tmp_path / "stair.dxf")
    with pytest.raises(RoomFileError, match="stair 's' has no bottom"):
        pedmesh.load_room(tmp_path / "stair.dxf")
