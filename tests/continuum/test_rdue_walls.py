"""rdue against walls: a cell whose route points into a wall must not trap its people."""

from __future__ import annotations

import numpy as np

from pedmesh import Exit, Obstacle, Room, StartArea
from pedmesh.models.continuum.solver import _slide_along_walls
from pedmesh.models import get_model
from pedmesh.mesh import triangulate


def test_slide_removes_only_the_part_into_the_walls():
    n = np.array([[[0.0, 1.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]],   # a wall above
                  [[0.0, 1.0], [1.0, 0.0], [0.0, 0.0], [0.0, 0.0]],   # a corner
                  [[0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]]])  # no wall
    e = np.array([[[0.6, 0.8], [0.6, -0.8]],
                  [[0.6, 0.8], [-0.6, 0.8]],
                  [[0.6, 0.8], [0.0, 0.0]]])
    out = _slide_along_walls(e, n)
    assert np.allclose(out[0], [[1.0, 0.0], [0.6, -0.8]])  # into the wall: along it
    assert np.allclose(out[1], [[0.0, 0.0], [-1.0, 0.0]])  # into both walls of a corner: 0
    assert np.array_equal(out[2], e[2])  # untouched away from walls, zero stays zero
    assert np.array_equal(e[0], [[0.6, 0.8], [0.6, -0.8]])  # (the input is not changed)


def test_people_in_front_of_a_pillar_face_are_not_trapped():
    """A pillar face square to the route, straight in front of the exit: the ridge of the
    route in the middle of the face trapped 0.3 people (of 60) for ever before the
    directions at the cells against walls were turned along them; now everyone is out
    within 20 s."""
    room = Room([(0, 0), (12, 0), (12, 6), (0, 6)], exits=[Exit("e", [(12, 2.5), (12, 3.5)])],
                obstacles=[Obstacle("pillar", [(7, 2), (8, 2), (8, 4), (7, 4)])],
                start_areas=[StartArea("crowd", [(0.5, 0.5), (5, 0.5), (5, 5.5), (0.5, 5.5)],
                                       count=60)])
    mesh = triangulate(room, max_area=0.3)
    factory = get_model("rdue").build
    run = factory(room, mesh, {})
    n0 = run.remaining
    while run.remaining > 1e-3 * n0 and run.t < 60.0:
        run.step()
    assert run.remaining <= 1e-3 * n0
    assert run.t < 20.0
