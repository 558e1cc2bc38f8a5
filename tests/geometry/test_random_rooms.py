"""Property tests: random valid rooms mesh and pass the area identity; random broken rooms
and corrupted files raise pedmesh errors, never anything else."""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import numpy as np
import shapely
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from pedmesh import PedmeshError, Room, load_room
from pedmesh.geometry.formats.native import room_from_dict, room_to_dict
from pedmesh.mesh import triangulate

SETTINGS = settings(max_examples=40, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])


@st.composite
def valid_rooms(draw):
    """A star-shaped outline, up to three square obstacles near its centre, exits on
    outline edges, and maybe a start area."""
    n = draw(st.integers(3, 9))
    gaps = np.array(draw(st.lists(st.floats(0.3, 1.0), min_size=n, max_size=n)))
    ang = np.cumsum(gaps / gaps.sum() * 2 * math.pi) + draw(st.floats(0, 2 * math.pi))
    assume(np.max(gaps / gaps.sum() * 2 * math.pi) <= 2 * math.pi / 3)
    rad = np.array(draw(st.lists(st.floats(5.0, 20.0), min_size=n, max_size=n)))
    cx, cy = draw(st.floats(-100, 100)), draw(st.floats(-100, 100))
    outline = [(cx + r * math.cos(a), cy + r * math.sin(a)) for r, a in zip(rad, ang)]
    # the star polygon contains the disc of radius 5 cos(60 deg) = 2.5 around the centre
    obstacles = []
    centres = []
    for k in range(draw(st.integers(0, 3))):
        r = draw(st.floats(0.0, 1.7))
        a = draw(st.floats(0, 2 * math.pi))
        ox, oy = cx + r * math.cos(a), cy + r * math.sin(a)
        if any(math.hypot(ox - px, oy - py) < 0.7 for px, py in centres):
            continue
        centres.append((ox, oy))
        h = 0.25
        obstacles.append({"name": f"o{k}", "polygon": [(ox - h, oy - h), (ox + h, oy - h),
                                                        (ox + h, oy + h), (ox - h, oy + h)]})
    exits = []
    edges = draw(st.lists(st.integers(0, n - 1), min_size=1, max_size=min(n, 3), unique=True))
    for j, e in enumerate(edges):
        a, b = np.array(outline[e]), np.array(outline[(e + 1) % n])
        s0 = draw(st.floats(0.05, 0.5))
        s1 = draw(st.floats(s0 + 0.05, 0.95))
        exits.append({"name": f"x{j}",
                      "polyline": [tuple(a + s0 * (b - a)), tuple(a + s1 * (b - a))]})
    start = []
    if draw(st.booleans()) and centres == []:
        start = [{"name": "s",
                  "polygon": [(cx - 1, cy - 1), (cx + 1, cy - 1), (cx + 1, cy + 1),
                              (cx - 1, cy + 1)],
                  "density": draw(st.floats(0.5, 4.0))}]
    return {"outline": outline, "obstacles": obstacles, "exits": exits, "start_areas": start}


@SETTINGS
@given(valid_rooms())
def test_random_valid_rooms_mesh(d):
    room = Room(**d)
    mesh = triangulate(room, max_area=room.area / 150.0, min_angle=25.0)
    exact = shapely.Polygon(room.outline).area - sum(o.shape.area for o in room.obstacles)
    assert abs(mesh.total_area - exact) <= 1e-9 * exact
    for k in range(len(room.exits)):
        err = abs(mesh.exit_lengths[k] - room.exit_length(k))
        assert err <= 1e-12 * room.exit_length(k) + 1e-15
    # (no angle bound here: random outlines have input corners sharper than 25 degrees)
    assert len(mesh.boundary_edges) == len(mesh.segments)
    # and the native format round-trips it exactly
    assert room_from_dict(json.loads(json.dumps(room_to_dict(room)))) == room


BAD_VALUES = [float("nan"), float("inf"), "1.5", None, True, [1, 2], {"x": 1}]


def _mutate(d: dict, which: int, data) -> dict:
    d = json.loads(json.dumps(d))  # deep copy (NaN-safe)
    cx = np.mean([p[0] for p in d["outline"]])
    cy = np.mean([p[1] for p in d["outline"]])
    if which == 0:  # a bad coordinate somewhere in the outline
        i = data.draw(st.integers(0, len(d["outline"]) - 1))
        d["outline"][i][data.draw(st.integers(0, 1))] = data.draw(st.sampled_from(BAD_VALUES))
    elif which == 1:  # obstacle far outside
        d["obstacles"] = [{"name": "far",
                           "polygon": [(cx + 500, cy), (cx + 501, cy), (cx + 501, cy + 1)]}]
    elif which == 2:  # obstacle larger than the room: crosses the outline
        d["obstacles"] = [{"name": "big", "polygon": [(cx - 30, cy - 0.5), (cx + 30, cy - 0.5),
                                                       (cx + 30, cy + 0.5), (cx - 30, cy + 0.5)]}]
    elif which == 3:  # two overlapping obstacles
        d["obstacles"] = [{"name": "a",
                           "polygon": [(cx, cy), (cx + 1, cy), (cx + 1, cy + 1), (cx, cy + 1)]},
                          {"name": "b",
                           "polygon": [(cx + .5, cy + .5), (cx + 1.5, cy + .5),
                                       (cx + 1.5, cy + 1.5)]}]
    elif which == 4:  # exit moved into the room
        p, q = np.array(d["exits"][0]["polyline"])
        d["exits"][0]["polyline"] = [list(0.5 * (p + [cx, cy])), list(0.5 * (q + [cx, cy]))]
    elif which == 5:  # zero-length exit
        p = d["exits"][0]["polyline"][0]
        d["exits"][0]["polyline"] = [p, list(p)]
    elif which == 6:  # bow-tie outline
        s = data.draw(st.floats(1.0, 50.0))
        d["outline"] = [(cx, cy), (cx + s, cy + s), (cx + s, cy), (cx, cy + s)]
    elif which == 7:  # unknown key
        d[data.draw(st.sampled_from(["exit", "walls", "obstacle", "Outline"]))] = []
    elif which == 8:  # start area with a bad parameter
        d["start_areas"] = [{"name": "s",
                             "polygon": [(cx - .5, cy - .5), (cx + .5, cy - .5), (cx, cy + .5)],
                             data.draw(st.sampled_from(["count", "spacing", "density"])):
                             data.draw(st.sampled_from([0, -1, float("nan"), "2", None]))}]
    elif which == 9:  # start area far outside the room
        d["start_areas"] = [{"name": "s",
                             "polygon": [(cx + 900, cy), (cx + 901, cy), (cx + 901, cy + 1)],
                             "count": 1}]
    elif which == 10:  # duplicated exit
        d["exits"].append(dict(d["exits"][0]))
    elif which == 11:  # polygon given as a string or number
        bad = data.draw(st.sampled_from(["abc", 3, None]))  # drawn first, as before
        d[data.draw(st.sampled_from(["outline", "obstacles", "exits"]))] = bad
    return d


@SETTINGS
@given(valid_rooms(), st.integers(0, 11), st.data())
def test_random_broken_rooms_raise_pedmesh_errors(d, which, data):
    broken = _mutate({**d, "obstacles": [], "start_areas": []}, which, data)
    try:
        room_from_dict(broken)
    except PedmeshError:
        return
    raise AssertionError(f"mutation {which} was accepted: {broken}")


@SETTINGS
@given(valid_rooms(), st.data())
def test_corrupted_files_raise_only_pedmesh_errors(d, data):
    text = json.dumps(room_to_dict(Room(**d)))
    op = data.draw(st.integers(0, 2))
    i = data.draw(st.integers(0, len(text) - 1))
    if op == 0:
        text = text[:i]
    elif op == 1:
        text = text[:i] + data.draw(st.sampled_from(list('{}[],:"0-.eaN '))) + text[i + 1:]
    else:
        text = text[:i] + text[i + 1:]
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "room.json"
        p.write_text(text)
        try:
            load_room(p)
        except PedmeshError:
            pass
