"""Room model: construction, derived quantities, start positions, exits on rings."""

from __future__ import annotations

import numpy as np
import pytest

from pedmesh import Exit, GeometryError, Obstacle, Room, StartArea
from pedmesh.geometry import EXIT_TOLERANCE

BOX = [(0, 0), (10, 0), (10, 5), (0, 5)]


def test_paper_start_block_is_the_papers_lattice(load_shipped):
    room = load_shipped("example2.json")
    x = room.initial_positions()
    assert x.shape == (2400, 2)
    i, j = np.meshgrid(np.arange(1, 49), np.arange(1, 51), indexing="ij")
    expected = np.column_stack([(i - 0.5).ravel(), (j - 0.5).ravel()])
    # paper numbering x_{50 i + j} = (i - 0.5, j - 0.5)
    np.testing.assert_array_equal(x, expected)


@pytest.mark.parametrize(
    ("kw", "n"),
    [({"count": 37}, 37), ({"spacing": 0.5}, 200), ({"density": 4.0}, 200)],
)
def test_start_area_count_spacing_density(kw, n):
    room = Room(BOX, exits=[Exit("e", [(10, 1), (10, 2)])],
                start_areas=[StartArea("s", [(0, 0), (10, 0), (10, 5), (0, 5)], **kw)])
    x = room.initial_positions()
    assert len(x) == n
    assert len(np.unique(x, axis=0)) == n
    assert np.all((x > 0) & (x < [10, 5]))


def test_start_area_must_avoid_obstacles():
    with pytest.raises(GeometryError, match="start area 's' overlaps obstacle 'o'"):
        Room(BOX, obstacles=[Obstacle("o", [(2, 1), (4, 1), (4, 3), (2, 3)])],
             start_areas=[StartArea("s", [(1, 0.5), (5, 0.5), (5, 4.5), (1, 4.5)], spacing=0.5)])


def test_exit_on_obstacle_and_around_a_corner():
    room = Room(
        BOX,
        obstacles=[Obstacle("stair", [(4, 2), (6, 2), (6, 3), (4, 3)])],
        exits=[Exit("corner", [(9, 0), (10, 0), (10, 1.5)]), Exit("stairs", [(4.5, 3), (5.5, 3)])],
    )
    rings = room.boundary_rings
    assert rings[0].exits == (0,) and rings[1].exits == (1,)
    assert room.exit_length(0) == pytest.approx(2.5, abs=1e-15)
    assert (9.0, 0.0) in rings[0].points and (10.0, 1.5) in rings[0].points
    assert (4.5, 3.0) in rings[1].points and (5.5, 3.0) in rings[1].points


def test_exit_within_tolerance_is_projected_onto_the_wall():
    off = 0.5 * EXIT_TOLERANCE
    room = Room(BOX, exits=[Exit("e", [(10 + off, 1), (10 - off, 2)])])
    assert room.exit_polyline(0) == ((10.0, 1.0), (10.0, 2.0))
    with pytest.raises(GeometryError, match="exit 'e' does not lie on"):
        Room(BOX, exits=[Exit("e", [(10 + 3 * EXIT_TOLERANCE, 1), (10, 2)])])


def test_room_is_immutable_and_revalidated():
    room = Room(BOX, exits=[Exit("e", [(10, 1), (10, 2)])])
    with pytest.raises(AttributeError):
        room.name = "x"  # type: ignore[misc]
    with pytest.raises(GeometryError, match="obstacle 'o' lies outside"):
        room.with_changes(obstacles=[Obstacle("o", [(20, 1), (21, 1), (21, 2)])])
    assert room.area == 50.0
    assert room.bounds == (0.0, 0.0, 10.0, 5.0)
    assert room.exit_index("e") == 0
    with pytest.raises(GeometryError, match="has no exit 'x'"):
        room.exit_index("x")


def test_closing_point_and_duplicates_are_dropped():
    room = Room(BOX + [(0, 0)], exits=[Exit("e", [(10, 1), (10, 1), (10, 2)])])
    assert room.outline == tuple((float(x), float(y)) for x, y in BOX)
    assert room.exits[0].polyline == ((10.0, 1.0), (10.0, 2.0))


def test_elements_from_dicts_and_numpy():
    room = Room(np.array(BOX, float),
                exits=[{"name": "e", "polyline": np.array([[10, 1], [10, 2]])}])
    assert room.exits[0] == Exit("e", [(10, 1), (10, 2)])
