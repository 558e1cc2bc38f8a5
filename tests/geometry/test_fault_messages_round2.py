"""Fault sweep, round 2 (issue 48): room and building files with a level height that is not
a number, a level named by a number, absurd coordinates, absurd population values, stairs
sharing an opening, and crowds whose memory the crowd limit did not see. Each is refused in
one line (a pedmesh error) naming the file's level or element, the value and the rule."""

from __future__ import annotations

import copy
import json
import math
import re
import tracemalloc
from pathlib import Path

import pytest

import pedmesh
from pedmesh.cli import main
from pedmesh.errors import GeometryError, ParameterError, PedmeshError, RoomFileError
from pedmesh.geometry import StartArea

from building_data import NOTCHED, TWO  # noqa: E402  (tests/building_data.py)

ROOT = Path(__file__).resolve().parents[2]


def _load(tmp_path, data, name="b.json"):
    p = tmp_path / name
    p.write_text(json.dumps(data))
    return pedmesh.load_room(p)


def _changed(change, data=TWO):
    data = copy.deepcopy(data)
    change(data)
    return data


def _one_line(capsys, path, tmp_path) -> str:
    assert main(["mesh", str(path), "-o", str(tmp_path / "m.vtu")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


# ------------------------------------------------------------------ 1: DXF numbers
def _dxf_building(path, z_first="z=3", start_text="spacing=1", stair_text="speed_up=0.5"):
    """TWO as a DXF drawing, with the given TEXTs on first.room, the start area's layer and
    the stair's layer."""
    import ezdxf

    doc = ezdxf.new("R2010")
    msp = doc.modelspace()

    def poly(layer, pts, closed=True):
        msp.add_lwpolyline(pts, close=closed, dxfattribs={"layer": layer})

    for level, z in (("ground", "z=0"), ("first", z_first)):
        poly(f"{level}.room", NOTCHED)
        msp.add_text(z, dxfattribs={"layer": f"{level}.room"})
    poly("ground.exit-front", [(0, 3), (0, 5)], closed=False)
    poly("first.start-offices", [(2, 1), (8, 1), (8, 6), (2, 6)])
    msp.add_text(start_text, dxfattribs={"layer": "first.start-offices"})
    poly("stair-s", [(8, 8), (12, 8), (12, 10), (8, 10)])
    poly("stair-s.bottom-ground", [(8, 8), (8, 10)], closed=False)
    poly("stair-s.top-first", [(12, 8), (12, 10)], closed=False)
    msp.add_text(stair_text, dxfattribs={"layer": "stair-s"})
    doc.saveas(path)
    return path


def test_dxf_building_reads(tmp_path):
    b = pedmesh.load_room(_dxf_building(tmp_path / "ok.dxf"))
    assert [lv.z for lv in b.levels] == [0.0, 3.0] and b.stairs[0].speed_up == 0.5


@pytest.mark.parametrize(("texts", "message"), [
    ({"z_first": "z=abc"}, "level 'first' (layer 'first.room'): z='abc' is not a number "
                           "(expected z=HEIGHT, the level's height in m)"),
    ({"z_first": "z=1.2.3"}, "level 'first' (layer 'first.room'): z='1.2.3' is not a number"),
    ({"z_first": "z=inf"}, "level 'first' (layer 'first.room'): z='inf' is not a finite "
                           "number"),
    ({"start_text": "count=1.2.3"}, "layer 'first.start-offices': count='1.2.3' is not a "
                                    "number"),
    ({"start_text": "density=lots"}, "layer 'first.start-offices': density='lots' is not a "
                                     "number"),
    ({"stair_text": "speed_up=fast"}, "stair 's': speed_up='fast' is not a number"),
])
def test_a_dxf_number_that_is_not_a_number_says_so(tmp_path, capsys, texts, message):
    """z=abc was reported as a missing 'z='; z=1.2.3 (and count=1.2.3) ended as a
    ValueError ('could not convert string to float')."""
    path = _dxf_building(tmp_path / "b.dxf", **texts)
    with pytest.raises(RoomFileError) as info:
        pedmesh.load_room(path)
    assert f"{path}: {message}" in str(info.value)
    assert "needs one TEXT" not in str(info.value)
    assert message in _one_line(capsys, path, tmp_path)


def test_a_dxf_count_that_is_not_whole_is_not_truncated(tmp_path):
    """count=2.5 became 2 people; now the start area refuses it."""
    with pytest.raises(GeometryError, match="start area 'offices': count must be a whole "
                                            "number, got 2.5"):
        pedmesh.load_room(_dxf_building(tmp_path / "b.dxf", start_text="count=2.5"))


# ------------------------------------------------------------------ 2: a level's name
def test_a_level_named_by_a_number_says_which_level(tmp_path, capsys):
    """'name': 3 said 'room name must be a string'."""
    data = _changed(lambda d: d["levels"][1].update(name=3))
    with pytest.raises(GeometryError) as info:
        _load(tmp_path, data)
    assert str(info.value) == (f"{tmp_path / 'b.json'}: levels[1]: the level's name must be "
                               "a non-empty string, got 3 (int)")
    assert "levels[1]: the level's name" in _one_line(capsys, tmp_path / "b.json", tmp_path)
    data = _changed(lambda d: d["stairs"][0].update(name=7.5))
    with pytest.raises(GeometryError, match=r"stairs\[0\]: the stair's name must be a "
                                            r"non-empty string, got 7.5 \(float\)"):
        _load(tmp_path, data)
    with pytest.raises(GeometryError, match=r"room name must be a string, got 3 \(int\)"):
        pedmesh.Room([(0, 0), (1, 0), (1, 1)], name=3)


# ------------------------------------------------------------------ 3: coordinates, levels
@pytest.mark.parametrize(("change", "message"), [
    (lambda d: d["levels"][1].update(outline=[[0, 0], [1e300, 0], [0, 1e300]]),
     "level 'first': room outline: point 1 has a coordinate of 1e+300 m (coordinates must "
     "be finite and within [-1e7, 1e7] m)"),
    (lambda d: d["levels"][1].update(outline=[[0, 0], [1e300, 0], [1e300, 1e300],
                                              [0, 1e300]]),
     "level 'first': room outline: point 1 has a coordinate of 1e+300 m"),
    (lambda d: d["levels"][1].update(outline=[[0, 0], [10, 10], [10, 0], [0, 10]]),
     "level 'first': room outline: the outline intersects itself"),
    (lambda d: d["levels"][1]["start_areas"][0].update(polygon=[[30, 1], [31, 1], [31, 2]]),
     "level 'first': start area 'offices' is not inside the room"),
    (lambda d: d["levels"][0]["exits"][0].update(polyline=[[0, 3], [0, 2e7]]),
     "level 'ground': exit 'front': point 1 has a coordinate of 2e+07 m"),
    (lambda d: d["levels"][1].update(z=1e300),
     "level 'first': 'z' must be a finite height in m within [-1e7, 1e7], got 1e+300"),
    (lambda d: d["stairs"][0].update(polygon=[[8, 8], [12, 8], [12, 1e12], [8, 10]]),
     "stair 'stair': point 2 has a coordinate of 1e+12 m"),
])
def test_geometry_errors_in_a_building_name_the_level(tmp_path, capsys, change, message):
    """1e300 said 'zero area', a bow tie 'the outline intersects itself' and a misplaced
    start area 'is not inside the room', none of them naming the level."""
    with pytest.raises(GeometryError) as info:
        _load(tmp_path, _changed(change))
    assert message in str(info.value)
    assert message in _one_line(capsys, tmp_path / "b.json", tmp_path)


@pytest.mark.parametrize("value", [1e300, -1.5e7, float("inf"), float("nan")])
def test_absurd_coordinates_are_refused_by_value(value):
    shown = f"{value:g} m" if math.isfinite(value) else f"non-finite coordinate {value!r}"
    with pytest.raises(GeometryError, match=r"room outline: point 2 has a (coordinate of )?"
                                            + shown.replace("+", r"\+")
                                            + r" \(coordinates must be finite and within "
                                            r"\[-1e7, 1e7\] m\)"):
        pedmesh.Room([(0, 0), (10, 0), (10, value), (0, 10)])
    pedmesh.Room([(-1e7, -1e7), (1e7, -1e7), (1e7, 1e7)])  # (the limits themselves pass)


# ------------------------------------------------------------------ 4: population ranges
SQUARE = [(1, 1), (4, 1), (4, 4), (1, 4)]
_U = "m/s (the range of the models' free speed U_f, which it replaces)"
_R = "m (the range of the models' body radius r, which it replaces)"


@pytest.mark.parametrize(("values", "message"), [
    ({"speed": 1e6}, f"'speed': values must be in [0.1, 5] {_U}, got 1e+06"),
    ({"speed": 0.01}, f"'speed': values must be in [0.1, 5] {_U}, got 0.01"),
    ({"speed": {"distribution": "uniform", "min": 0.5, "max": 40}},
     f"'speed': values must be in [0.1, 5] {_U}, got 'max' 40"),
    ({"speed": {"distribution": "lognormal", "mu": 0.3, "sigma": 2.0}},
     f"'speed': values must be in [0.1, 5] {_U}, got 0.000794 at its 0.01 % quantile (give "
     "'min' to truncate it)"),
    ({"radius": 3.0}, f"'radius': values must be in [0.05, 1] {_R}, got 3"),
    ({"radius": {"distribution": "uniform", "min": 0.01, "max": 0.2}},
     f"'radius': values must be in [0.05, 1] {_R}, got 'min' 0.01"),
    ({"premovement": 1e9}, "'premovement': values must be in [0, 3600] s (at most an hour), "
                           "got 1e+09"),
    ({"premovement": {"distribution": "normal", "mean": 600, "sd": 2000, "min": 0}},
     "'premovement': values must be in [0, 3600] s (at most an hour), got 8.28e+03 at its "
     "99.99 % quantile (give 'max' to truncate it)"),
])
def test_population_values_have_physical_ranges(tmp_path, capsys, values, message):
    """A speed of 1e6 m/s, a radius of 3 m or a premovement of 30 years were taken."""
    data = {"outline": [[0, 0], [10, 0], [10, 5], [0, 5]],
            "exits": [{"name": "door", "polyline": [[10, 2], [10, 3]]}],
            "start_areas": [{"name": "crowd", "polygon": SQUARE, "count": 5, **values}]}
    with pytest.raises(GeometryError) as info:
        _load(tmp_path, data, "room.json")
    assert f"start area 'crowd': {message}" in str(info.value)
    assert message in _one_line(capsys, tmp_path / "room.json", tmp_path)


def test_the_ends_of_the_ranges_and_given_distributions_are_checked():
    from pedmesh.population import Distribution

    for key, lo, hi in (("speed", 0.1, 5.0), ("radius", 0.05, 1.0),
                        ("premovement", 0.0, 3600.0)):
        StartArea("a", SQUARE, count=3, **{key: lo})
        StartArea("a", SQUARE, count=3, **{key: hi})
        StartArea("a", SQUARE, count=3,
                  **{key: {"distribution": "uniform", "min": lo, "max": hi}})
    with pytest.raises(GeometryError, match="'speed': values must be in"):
        StartArea("a", SQUARE, count=3, speed=Distribution("constant", value=50.0))
    # the count is a positive whole number and the density at most 10 /m^2
    for bad, match in (({"count": 0}, "count must be a positive"),
                       ({"count": 2.5}, "count must be a whole number"),
                       ({"density": 11.0}, "more than the 10 /m^2 of the densest crowds")):
        with pytest.raises(GeometryError, match=re.escape(match)):
            StartArea("a", SQUARE, **bad)


def test_shipped_and_example_rooms_still_load():
    files = sorted((ROOT / "geometries").rglob("*.json"))
    files += sorted((ROOT / "examples").rglob("*.json"))
    files += [ROOT / "geometries" / n for n in ("l_shaped.dxf", "pillar_hall.geojson",
                                                "foyer.svg")]
    loaded = 0
    for f in files:
        if f.suffix == ".json" and not {"outline", "levels"} & set(json.loads(f.read_text())):
            continue
        pedmesh.load_room(f)
        loaded += 1
    assert loaded >= 20


# ------------------------------------------------------------------ 5: what is allocated
def _peak_bytes(fn) -> tuple[object, int]:
    tracemalloc.start()
    try:
        out = fn()
        return out, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_a_lattice_allocates_for_its_people_not_its_bounding_box():
    """A strip 0.5 m wide along the diagonal of a 2 km square holds about 14,000 people at
    10 /m^2 (well within the crowd limit), but the lattice was made over its bounding box
    first: 4e7 points, 1.3 GB (along a 10 km square's diagonal: 1e9 points, 32 GB)."""
    L, w = 2000.0, 0.25 * math.sqrt(2)
    area = StartArea("strip", [(0, 0), (w, -w), (L + w, L - w), (L, L)], density=10.0)
    assert area.expected_count == pytest.approx(10 * 0.5 * L * math.sqrt(2))
    pts, peak = _peak_bytes(area.positions)
    assert len(pts) > area.expected_count
    assert peak < 200e6, f"{peak / 1e6:.0f} MB"


def test_a_lattice_made_in_blocks_is_the_same_lattice(monkeypatch):
    """The blocks give the same points (every bit) in the same order (x slowest)."""
    import shapely
    from shapely.geometry import Polygon

    import pedmesh.geometry.room as R

    areas = [StartArea("l", [(0.3, 0.1), (20, 0.1), (20, 3), (3, 3), (3, 17.7), (0.3, 17.7)],
                       spacing=0.5),
             StartArea("d", [(-503.2, 100), (-480, 120.5), (-482, 123), (-505, 102.5)],
                       density=3.0)]
    hole = Polygon([(-600, -100), (100, -100), (100, 300), (-600, 300)],
                   [[(1, 1), (2, 1), (2, 9), (1, 9)], [(-495, 105), (-490, 110), (-495, 112)]])
    for area in areas:
        for region in (None, hole):
            whole = area.positions(region)
            monkeypatch.setattr(R, "LATTICE_BLOCK", 7)
            blocks = area.positions(region)
            monkeypatch.undo()
            assert whole.shape == blocks.shape and len(whole) > 20
            assert whole.tobytes() == blocks.tobytes()
            if region is not None:
                assert shapely.contains_xy(region, *blocks.T).all()


def test_an_entrance_allocates_nothing_per_person_until_the_run_checks_the_crowd():
    """An entrance's arrival times were made when the file was read: 'count': 30000000
    took about 1 GB (and 1e9, 30 GB or more) before a run could refuse the crowd's size."""
    from pedmesh.run.driver import check_crowd

    gate = [(0, 0), (2, 0), (2, 2), (0, 2)]
    room, peak = _peak_bytes(lambda: pedmesh.Room(
        [(0, 0), (10, 0), (10, 5), (0, 5)], exits=[{"name": "d", "polyline": [(10, 2),
                                                                               (10, 3)]}],
        start_areas=[StartArea("gate", gate, count=30_000_000, arrivals={"rate": 2.0})]))
    assert peak < 20e6, f"{peak / 1e6:.0f} MB"
    with pytest.raises(ParameterError, match="about 3e\\+07 people, more than the limit"):
        check_crowd(room)
    small = StartArea("gate", gate, count=4, arrivals={"rate": 2.0, "start": 1.0})
    assert small.arrivals.times == (1.0, 1.5, 2.0, 2.5) and small.arrivals.count == 4
    assert small == StartArea("gate", gate, count=4, arrivals=small.arrivals)
    with pytest.raises(AttributeError):
        small.arrivals.rate = 3.0


# ------------------------------------------------------------------ stairs sharing an edge
def test_two_stairs_sharing_an_opening_are_named_by_their_names(tmp_path, capsys):
    """A second stair leaving 'first' through the opening the first stair arrives at gave
    "exit '\u2195hinge:stair:top' overlaps exit '\u2195hinge:upper:bottom'" when meshed."""
    def add(d):
        d["levels"].append({"name": "second", "z": 6.0, "outline": NOTCHED})
        d["stairs"].append({"name": "upper", "polygon": [[8, 8], [12, 8], [12, 10], [8, 10]],
                            "bottom": {"level": "first", "edge": [[12, 8], [12, 10]]},
                            "top": {"level": "second", "edge": [[8, 8], [8, 10]]}})

    message = ("stair 'stair': its top edge overlaps the bottom edge of stair 'upper' on "
               "level 'first' (2 m in common; each stair needs its own opening in the "
               "level's wall)")
    with pytest.raises(GeometryError) as info:
        _load(tmp_path, _changed(add))
    assert message in str(info.value) and "hinge" not in str(info.value)
    err = _one_line(capsys, tmp_path / "b.json", tmp_path)
    assert message in err and "hinge" not in err
    assert isinstance(info.value, PedmeshError)
