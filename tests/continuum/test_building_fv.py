"""The continuum models on a building's surface: the glued atlas (one interior edge per stair
edge, each cell in its own chart), mass conserved to round-off across stairs, positivity,
the stair's speed, and a flat connector that answers like the flat room."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from pedmesh.geometry import Building, Exit, Level, Room, Stair, StartArea
from pedmesh.io import load_room
from pedmesh.mesh import TriMesh
from pedmesh.mesh.atlas import build_atlas
from pedmesh.mesh.building import triangulate_building
from pedmesh.models import get_model

ROOT = __import__("pathlib").Path(__file__).resolve().parents[2]


def strip(rise: float, density: float = 2.0, run: float = 4.0) -> Building:
    """A 4 m wide strip: level 'a' (x in [0, 10], z = 0, a 1 m door at x = 0), a stair
    on x in [10, 10 + run] and level 'b' beyond it, ``rise`` m up, with a crowd."""
    x1, x2 = 10.0, 10.0 + run
    a = Room(outline=[(0, 0), (x1, 0), (x1, 4), (0, 4)], name="a",
             exits=[Exit("door", [(0, 2.5), (0, 1.5)])])
    crowd = StartArea("crowd", [(x2 + 2, 0.5), (x2 + 8, 0.5), (x2 + 8, 3.5), (x2 + 2, 3.5)],
                      density=density)
    b = Room(outline=[(x2, 0), (x2 + 10, 0), (x2 + 10, 4), (x2, 4)], name="b",
             start_areas=[crowd])
    st = Stair("ramp", [(x1, 0), (x2, 0), (x2, 4), (x1, 4)],
               {"level": "a", "edge": [(x1, 0), (x1, 4)]},
               {"level": "b", "edge": [(x2, 0), (x2, 4)]})
    return Building([Level("a", 0.0, a), Level("b", rise, b)], [st], name="strip")


def _run(room, mesh, model: str, t_end: float = 300.0, **params):
    r = get_model(model).build(room, mesh, params)
    rho_min = np.inf
    while not r.done and r.t < t_end:
        r.step()
        rho_min = min(rho_min, float(r.state.Q[:, 0].min()))
    return r, rho_min


def test_the_glued_atlas_is_the_surface_laid_flat():
    b = load_room(ROOT / "geometries" / "office.json")
    s = triangulate_building(b)
    a = build_atlas(s)
    g = a.glued
    # the same cells, the true areas; one edge per surface edge, stair edges interior
    assert g.n_triangles == s.n_triangles and g.n_edges == len(s.edges)
    assert np.allclose(g.areas, s.areas, rtol=1e-12)
    surf_edges = np.sort(a.to_surface[g.edges], axis=1)
    order = np.lexsort((surf_edges[:, 1], surf_edges[:, 0]))
    assert np.array_equal(surf_edges[order], s.edges)
    assert np.allclose(g.edge_lengths[order], s.edge_lengths, rtol=1e-12)
    assert len(g.boundary_edges) == int(np.sum(s.edge_triangle_counts == 1))
    # stacked floors lie side by side: no two pieces overlap in the atlas
    import shapely

    regions = [shapely.union_all(shapely.polygons(g.points[g.triangles[p.triangles]]))
               for p in s.pieces]
    for i in range(len(regions)):
        for j in range(i + 1, len(regions)):
            assert regions[i].intersection(regions[j]).area < 1e-9
    # across a stair edge the two frames differ by a translation: the right cell's copy of
    # the edge, moved by cell_shift, is the left cell's
    L, R = g.edge_triangles[:, 0], g.edge_triangles[:, 1]
    cross = np.flatnonzero((R >= 0) & (g.piece[L] != g.piece[np.maximum(R, 0)]))
    assert len(cross) > 0
    for e in cross:
        mine = {int(a.to_surface[v]): g.points[v] for v in g.triangles[R[e]]}
        for v in g.edges[e]:
            moved = mine[int(a.to_surface[v])] + g.cell_shift(L[e], R[e])
            assert np.allclose(moved, g.points[v], atol=1e-9)
    # a stair's top edge moves by the slope's length less the run's, along the run
    st = b.stairs[0]
    k = s.piece_index(st.name)
    top = s.piece_index(st.top.level)
    d, run = st.run_direction()
    extra = math.hypot(run, b.rise(st)) - run
    assert np.allclose(g.piece_shift[top, k] + a.offset[k] - a.offset[top], -extra * d,
                       atol=1e-9)


@pytest.mark.parametrize("model", ["eos", "rdue", "pw"])
def test_mass_is_conserved_across_a_stair(model):
    """Everyone comes down a 3 m stair and out: the mass error stays at round-off, the
    density non-negative, and the crowd leaves by the door."""
    b = strip(3.0)
    s = triangulate_building(b, max_area=0.3, feature_area=None)
    r, rho_min = _run(b, s, model)
    summary = r.summary()
    assert r.done
    assert summary["mass_error_max"] < 1e-13 * summary["n_initial"]
    assert rho_min >= 0.0
    assert math.isclose(summary["n_evacuated"] + r.remaining, summary["n_initial"],
                        rel_tol=1e-12)


def test_a_stair_slows_the_crowd_down():
    """The same crowd takes longer over a 3 m stair (its slope longer, its speed 0.6 of the
    level's going down) than over a flat connector."""
    t = {}
    for rise in (0.0, 3.0):
        b = strip(rise, density=0.5)
        s = triangulate_building(b, max_area=0.3, feature_area=None)
        r, _ = _run(b, s, "rdue")
        t[rise] = r.summary()["t_evac_50"]
    st = strip(3.0).stairs[0]
    # at low density (free flow) the half-way crowd crosses 5 m of slope at 0.6 U instead of
    # 4 m at U: about 4.3 s more at U = 1.34 m/s
    U = get_model("rdue").build(strip(0.0), triangulate_building(strip(0.0), max_area=1.0),
                                {}).model.U_f
    expected = (5.0 / st.speed_down - 4.0) / U
    assert t[3.0] - t[0.0] == pytest.approx(expected, rel=0.25)


def _flat_twin(b: Building, s):
    """The strip without its stair: one flat room on the same triangles (numbered as the
    surface's)."""
    room = Room(outline=[(0, 0), (24, 0), (24, 4), (0, 4)], name="flat",
                exits=[Exit("door", [(0, 2.5), (0, 1.5)])],
                start_areas=list(b.levels[1].room.start_areas))
    flat = TriMesh(points=s.points[:, :2], triangles=s.triangles, segments=s.segments,
                   segment_kind=s.segment_kind, segment_owner=s.segment_owner,
                   exit_names=s.exit_names, room=room)
    return room, flat


@pytest.mark.parametrize("model", ["eos", "rdue", "pw"])
def test_a_flat_connector_answers_like_the_flat_room_bit_for_bit(model):
    """A stair without rise joins two levels like the floor it replaces: on the same
    triangles as one flat room, the same numbers to the last bit (the routes, the steering
    and the fluxes see no edge where the surface does not fold)."""
    b = strip(0.0)
    s = triangulate_building(b, max_area=0.3, feature_area=None)
    room, flat = _flat_twin(b, s)
    rb, _ = _run(b, s, model)
    rf, _ = _run(room, flat, model)
    sb, sf = rb.summary(), rf.summary()
    for key in ("n_initial", "t_evac_50", "t_evac_90", "t_evac_100", "steps"):
        if key in sb:
            assert sb[key] == sf[key], key
    assert np.array_equal(rb.state.Q, rf.state.Q)


def test_models_without_surface_support_say_so():
    b = strip(3.0)
    s = triangulate_building(b, max_area=1.0)
    from pedmesh.errors import ParameterError

    with pytest.raises(ParameterError, match="does not run on buildings"):
        get_model("mac1").build(b, s, {})
