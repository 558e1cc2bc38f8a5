"""Geometry files: native JSON round trips exactly; GeoJSON and DXF read the same rooms."""

from __future__ import annotations

import dataclasses
import json
import math

import pytest

from pedmesh import Room, load_room, save_room
from pedmesh.geometry.formats import formats

JSON_FILES = ["example1.json", "example2.json", "example3.json", "corridor_bottleneck.json",
              "l_shaped.json", "pillar_hall.json"]


@pytest.mark.parametrize("name", JSON_FILES)
def test_native_round_trip_is_exact(name, load_shipped, tmp_path):
    room = load_shipped(name)
    out = save_room(room, tmp_path / name)
    again = load_room(out)
    assert again == room
    # saving again writes the same bytes
    out2 = save_room(again, tmp_path / ("2" + name))
    assert out.read_bytes() == out2.read_bytes()


def test_native_round_trip_keeps_every_float_bit(tmp_path):
    x = 0.1 + 0.2  # 0.30000000000000004
    room = Room([(0, 0), (10 * x, 0), (10 * x, math.pi), (0, math.pi)],
                exits=[{"name": "e", "polyline": [(10 * x, 1 / 3), (10 * x, 2 / 3)]}],
                start_areas=[{"name": "s", "polygon": [(0.1, 0.1), (1, 0.1), (1, 1)],
                              "density": 1 / 7}])
    again = load_room(save_room(room, tmp_path / "r.json"))
    assert again == room
    assert again.start_areas[0].density == 1 / 7


def test_geojson_matches_json(load_shipped):
    assert load_shipped("pillar_hall.geojson") == load_shipped("pillar_hall.json")


def test_dxf_matches_json(load_shipped):
    assert load_shipped("l_shaped.dxf") == load_shipped("l_shaped.json")


@pytest.mark.parametrize("suffix", [".geojson", ".dxf"])
def test_other_formats_round_trip(suffix, load_shipped, tmp_path):
    for name in JSON_FILES:
        room = load_shipped(name)
        again = load_room(save_room(room, tmp_path / (name + suffix)))
        if suffix == ".dxf":  # (a DXF drawing carries no parameter preset)
            room = dataclasses.replace(room, preset=None)
        assert again == room, name


def test_geojson_room_holes_become_obstacles(tmp_path):
    fc = {
        "type": "FeatureCollection",
        "features": [
            {"type": "Feature", "properties": {"role": "room", "name": "r"},
             "geometry": {"type": "Polygon", "coordinates": [
                 [[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]],
                 [[4, 4], [6, 4], [6, 6], [4, 6], [4, 4]]]}},
            {"type": "Feature", "properties": {"role": "exit"},
             "geometry": {"type": "LineString", "coordinates": [[10, 1], [10, 3]]}},
        ],
    }
    p = tmp_path / "r.geojson"
    p.write_text(json.dumps(fc))
    room = load_room(p)
    assert room.obstacle_names == ("hole-1",)
    assert room.exit_names == ("exit-1",)
    assert room.area == pytest.approx(96.0)


def test_dxf_circle_pillar_and_start_text(tmp_path):
    import ezdxf

    doc = ezdxf.new()
    msp = doc.modelspace()
    msp.add_lwpolyline([(0, 0), (20, 0), (20, 10), (0, 10)], close=True,
                       dxfattribs={"layer": "ROOM"})
    msp.add_circle((10, 5), 1.0, dxfattribs={"layer": "obstacle-pillar"})
    msp.add_line((20, 4), (20, 6), dxfattribs={"layer": "Exit_east"})
    msp.add_lwpolyline([(1, 1), (5, 1), (5, 9), (1, 9)], close=True, dxfattribs={"layer": "start"})
    msp.add_text("density=2", dxfattribs={"layer": "start"})
    msp.add_line((0, 0), (50, 50), dxfattribs={"layer": "annotations"})  # ignored
    p = tmp_path / "c.dxf"
    doc.saveas(p)
    room = load_room(p)
    assert room.obstacle_names == ("pillar",)
    assert room.exit_names == ("east",)
    assert room.start_areas[0].density == 2.0
    # the circle is flattened to within 1 cm: its area is close to pi
    assert room.obstacles[0].shape.area == pytest.approx(math.pi, rel=2e-2)
    assert room.obstacles[0].shape.area < math.pi


def test_registered_formats():
    assert {".json", ".geojson", ".dxf"} <= set(formats())
