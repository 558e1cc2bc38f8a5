"""Crowd-safety measures (pedmesh.analysis.safety, pedmesh.run.safety) on constructed cases
with known answers, and end to end: every run records them in summary.json."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from pedmesh import Exit, MeasurementArea, Room, StartArea
from pedmesh.analysis import kernel_density, vertex_to_cell
from pedmesh.analysis import safety as S
from pedmesh.mesh import triangulate
from pedmesh.run.output import RunWriter
from pedmesh.run.safety import SAFETY_KEYS, safety_measures


def _box(w: float, h: float, **kw) -> Room:
    return Room([(0, 0), (w, 0), (w, h), (0, h)], exits=[Exit("door", [(w, 0), (w, 1)])],
                **kw)


def test_fruin_tables_in_metric_units():
    walk = [(lv.letter, round(lv.min_space_m2, 2)) for lv in S.FRUIN_WALKWAY]
    assert walk == [("A", 3.25), ("B", 2.32), ("C", 1.39), ("D", 0.93), ("E", 0.46),
                    ("F", 0.0)]
    queue = [(lv.letter, round(lv.min_space_m2, 2)) for lv in S.FRUIN_QUEUING]
    assert queue == [("A", 1.21), ("B", 0.93), ("C", 0.65), ("D", 0.28), ("E", 0.19),
                     ("F", 0.0)]
    # a space exactly on a bound is the better level; just below it, the next
    on = 1.0 / (35 * S.FT2)
    assert S.level_of_service(density=np.array([0.0, on, on * 1.001])).tolist() == [0, 0, 1]


def test_uniform_crowd_of_3_per_m2_is_fruin_F_on_walkways_and_D_in_queues():
    """3 /m^2 is 0.33 m^2 (3.6 ft^2) per person: below walkway E's 5 ft^2, so F (issue 34
    said E; Fruin's walkway table gives F), and within the queuing scale's D (3-7 ft^2)."""
    room = _box(10.0, 8.0)
    mesh = triangulate(room, max_area=0.3)
    t = np.arange(0.0, 5.5, 1.0)
    rho = np.full((len(t), mesh.n_triangles), 3.0)
    local = S.local_density(density=rho, centroids=mesh.centroids, areas=mesh.areas)
    assert np.allclose(local, 3.0, rtol=1e-12)
    peak = S.peak_density(t=t, density=local, centroids=mesh.centroids)
    assert peak.value == pytest.approx(3.0, rel=1e-12)
    worst = S.worst_level_of_service(density=local)
    assert set(S.los_letter(w) for w in worst) == {"F"}
    queuing = S.worst_level_of_service(density=local, scale="queuing")
    assert set(S.los_letter(w) for w in queuing) == {"D"}
    assert S.area_time_above(t=t, density=local, areas=mesh.areas) == pytest.approx(
        {2.0: 80.0 * 5.0, 4.0: 0.0, 6.0: 0.0})


def test_uniform_particle_crowd_of_3_per_m2_reads_3_on_1_m2():
    """The social force model's path: kernel density at the vertices, averaged to the
    cells and over 1 m^2, of a lattice at 3 /m^2 is 3 away from the crowd's edge."""
    room = _box(20.0, 20.0)
    mesh = triangulate(room, max_area=0.5)
    a = 1.0 / math.sqrt(3.0)
    g = np.arange(-4.0, 24.0, a)  # the crowd goes on beyond the walls: no edge effect
    X, Y = np.meshgrid(g, g, indexing="ij")
    pos = np.column_stack([X.ravel(), Y.ravel()])
    vd = kernel_density(positions=pos, points=mesh.points, R=0.7)
    cells = vertex_to_cell(mesh=mesh, values=vd)
    local = S.local_density(density=cells, centroids=mesh.centroids, areas=mesh.areas)
    assert np.allclose(local, 3.0, rtol=2e-3)
    assert set(S.level_of_service(density=local).tolist()) == {5}


def test_crowd_standing_10_s_on_20_m2_above_4_gives_200_m2_s():
    room = _box(5.0, 4.0)  # 20 m^2, all of it at 5 /m^2
    mesh = triangulate(room, max_area=0.3)
    t = np.arange(0.0, 10.5, 1.0)  # frames at 0, 1, ..., 10 s
    rho = np.full((len(t), mesh.n_triangles), 5.0)
    local = S.local_density(density=rho, centroids=mesh.centroids, areas=mesh.areas)
    at = S.area_time_above(t=t, density=local, areas=mesh.areas)
    assert at[4.0] == pytest.approx(200.0, rel=1e-12)
    assert at[2.0] == pytest.approx(200.0, rel=1e-12) and at[6.0] == 0.0
    assert S.time_above(t=t, density=local) == pytest.approx({2.0: 10.0, 4.0: 10.0,
                                                              6.0: 0.0})


def test_frame_weights_cover_the_frames_span():
    w = S.frame_weights(t=np.array([0.0, 1.0, 2.0, 4.0]))
    assert w.tolist() == [0.5, 1.0, 1.5, 1.0]
    assert S.frame_weights(t=np.array([3.0])).tolist() == [0.0]


def test_peak_density_says_where_and_when():
    c = np.array([[0.5, 0.5], [1.5, 0.5], [2.5, 0.5]])
    d = np.array([[1.0, 2.0, 0.0], [1.0, 4.5, 0.0], [3.0, 1.0, 0.0]])
    p = S.peak_density(t=np.array([0.0, 1.0, 2.0]), density=d, centroids=c)
    assert (p.value, p.t, p.x, p.y, p.cell) == (4.5, 1.0, 1.5, 0.5, 1)
    assert p.per_cell.tolist() == [3.0, 4.5, 0.0]
    assert p.t_per_cell[:2].tolist() == [2.0, 1.0] and math.isnan(p.t_per_cell[2])


def test_one_square_metre_average_of_a_point_peak():
    """A single hot cell on a fine mesh is averaged over the cells within 1 m^2."""
    room = _box(6.0, 6.0)
    mesh = triangulate(room, max_area=0.05)
    i = int(np.argmin(np.hypot(*(mesh.centroids - [3.0, 3.0]).T)))
    rho = np.zeros(mesh.n_triangles)
    rho[i] = 10.0
    local = S.local_density(density=rho, centroids=mesh.centroids, areas=mesh.areas)
    near = np.hypot(*(mesh.centroids - mesh.centroids[i]).T) <= S.ONE_SQUARE_METRE_RADIUS
    assert local[i] == pytest.approx(10.0 * mesh.areas[i] / mesh.areas[near].sum())
    assert local.max() < 10.0 * 0.2  # 1 m^2 holds many cells of 0.05 m^2


def test_single_walker_has_no_crowd_pressure():
    g = np.linspace(-3.0, 3.0, 31)
    X, Y = np.meshgrid(g, g)
    pts = np.column_stack([X.ravel(), Y.ravel()])
    cp = S.crowd_pressure(positions=np.array([[0.1, -0.2]]),
                          velocities=np.array([[1.3, 0.4]]), points=pts, R=0.7)
    assert cp.density.max() > 0.5
    assert np.all(np.abs(cp.pressure) < 1e-12)
    frames = [(t, np.array([[0.1 + 1.3 * t, -0.2]]), np.array([[1.3, 0.0]]))
              for t in range(5)]
    peak = S.peak_crowd_pressure(frames=frames, points=pts, R=0.7)
    assert abs(peak.max) < 1e-12


def test_crowd_pressure_of_two_opposite_walkers():
    """Two people on one spot walking at +-v: V = 0, Var = v^2, rho = 2 / (pi R^2)."""
    v, R = 1.2, 0.7
    cp = S.crowd_pressure(positions=np.array([[0.0, 0.0], [0.0, 0.0]]),
                          velocities=np.array([[v, 0.0], [-v, 0.0]]),
                          points=np.array([[0.0, 0.0], [10.0, 10.0]]), R=R)
    assert cp.density[0] == pytest.approx(2.0 / (math.pi * R * R))
    assert cp.variance[0] == pytest.approx(v * v)
    assert cp.pressure[0] == pytest.approx(2.0 * v * v / (math.pi * R * R))
    assert cp.pressure[1] == 0.0 and cp.density[1] == 0.0


def test_exit_usage_from_a_flow():
    """2 ped/s from t = 0 to 10 s: 20 people, the 0.5th at 0.25 s, the 19.5th at 9.75 s."""
    t = np.round(np.arange(0.0, 12.01, 0.1), 10)
    flow = np.where((t > 0) & (t <= 10.0 + 1e-9), 2.0, 0.0)[:, None]
    u = S.exit_usage_from_flow(t=t, flow=flow, names=["door"])["door"]
    assert u.people == pytest.approx(20.0)
    assert u.first == pytest.approx(0.25) and u.last == pytest.approx(9.75)
    none = S.exit_usage_from_flow(t=t, flow=0.01 * flow, names=["door"])["door"]
    assert none.people == pytest.approx(0.2) and none.first is None and none.last is None


def test_clear_times():
    t = np.array([0.0, 1.0, 2.0, 3.0])
    assert S.clear_time(t=t, content=np.array([5.0, 2.0, 0.4, 0.1])) == pytest.approx(
        1.0 + 1.5 / 1.6)
    assert S.clear_time(t=t, content=np.array([5.0, 0.2, 0.7, 0.1])) == pytest.approx(
        2.0 + 0.2 / 0.6)  # the last time it was not clear counts
    assert S.clear_time(t=t, content=np.array([5.0, 3.0, 2.0, 1.0])) is None
    assert S.clear_time(t=t, content=np.zeros(4)) == 0.0
    et = np.array([3.0, 5.0, 4.0, 7.0, np.nan])
    assert S.group_clear_times(exit_times=et, counts=[3, 2, 0]) == [5.0, None, 0.0]


def _particle_folder(tmp_path):
    """A run folder written through RunWriter by hand: two start areas (3 and 2 people),
    a measurement area, and exits.csv with known crossings."""
    room = _box(10.0, 6.0, start_areas=[StartArea("left", [(1, 1), (3, 1), (3, 5), (1, 5)],
                                                  count=3),
                                        StartArea("right", [(5, 1), (7, 1), (7, 5), (5, 5)],
                                                  count=2)],
                measurement_areas=[MeasurementArea("hall", [(0, 0), (10, 0), (10, 6),
                                                            (0, 6)])])
    room = room.with_changes(exits=(Exit("east", [(10, 0), (10, 1)]),
                                    Exit("west", [(0, 5), (0, 6)])))
    mesh = triangulate(room, max_area=0.5)
    out = tmp_path / "run"
    w = RunWriter(out, {"model": "sfm"}, exit_names=mesh.exit_names)
    w.start({"parameters": {"R": 0.7}})
    crossings = [(0, "east", 4.0), (3, "west", 5.5), (1, "east", 6.0), (2, "east", 9.25),
                 (4, "west", 9.5)]
    pos0 = room.initial_positions()
    for k, t in enumerate(np.arange(0.0, 11.0, 1.0)):
        inside = [i for i in range(5) if not any(c[0] == i and c[2] <= t for c in crossings)]
        pos = pos0[inside]
        vel = np.tile([[1.0, 0.0]], (len(inside), 1))
        w.pedestrian_frame(t, pos, {"velocity": vel})
        w.density_frame(t, mesh, point_data={
            "density": kernel_density(positions=pos, points=mesh.points, R=0.7)})
        w.outflow(t, [0.0, 0.0])
    w.append_rows("exits.csv", "id,exit,t", [f"{i},{e},{t}" for i, e, t in crossings])
    w.finish(status="finished", n_initial=5)
    return room, mesh, out


def test_exit_passages_and_start_areas_from_a_constructed_exits_csv(tmp_path):
    room, mesh, out = _particle_folder(tmp_path)
    s = safety_measures(out, room, mesh, write_fields=True)
    assert s["exits"] == {"east": {"people": 3.0, "first": 4.0, "last": 9.25},
                          "west": {"people": 2.0, "first": 5.5, "last": 9.5}}
    # ids 0-2 are the first start area's, 3-4 the second's
    assert s["clear_times"]["start_areas"] == {"left": 9.25, "right": 9.5}
    hall = s["clear_times"]["measurement_areas"]["hall"]
    assert 9.0 < hall <= 10.0  # the last walker (gone at 9.5 s) is out of the 10 s frame
    assert s["crowd_pressure"]["max"] == pytest.approx(0.0, abs=1e-12)  # all walk as one
    assert s["level_of_service"]["cells_by_worst"]["A"] > 0
    assert sum(s["level_of_service"]["cells_by_worst"].values()) == mesh.n_triangles
    import pyvista as pv

    m = pv.read(out / "safety.vtu")
    assert m.n_cells == mesh.n_triangles
    assert np.allclose(m.cell_data["peak_density"].max(), s["peak_density"]["value"])
    assert {"worst_los", "worst_los_queuing", "time_above_4", "max_crowd_pressure"} <= \
        set(m.cell_data.keys())
    # without the room (its file is unknown here): no start or measurement areas
    s2 = safety_measures(out)
    assert s2["clear_times"] == {"start_areas": {}, "measurement_areas": {}}
    assert s2["exits"] == s["exits"]


def test_a_folder_without_frames_is_a_clear_error(tmp_path):
    from pedmesh.errors import PedmeshError

    with pytest.raises(PedmeshError, match="density.pvd"):
        safety_measures(tmp_path)


def _check_record(s: dict, model: str, n: int) -> None:
    assert tuple(s) == SAFETY_KEYS
    pk = s["peak_density"]
    assert set(pk) == {"value", "unit", "t", "x", "y", "over"} and pk["unit"] == "ped/m^2"
    assert 2.0 < pk["value"] < 12.0 and 0.0 <= pk["x"] <= 40.0 and 0.0 <= pk["y"] <= 6.0
    assert set(s["area_time_above"]) == {"2", "4", "6"} == set(s["time_above"])
    assert s["area_time_unit"] == "m^2 s"
    assert s["area_time_above"]["2"] >= s["area_time_above"]["4"] >= s["area_time_above"]["6"]
    los = s["level_of_service"]
    assert los["scale"] == "Fruin walkway" and los["worst"] == "F"
    assert list(los["cells_by_worst"]) == list("ABCDEF")
    ex = s["exits"]["end"]
    assert ex["people"] == pytest.approx(n, abs=0.5) and 0 < ex["first"] < ex["last"]
    assert s["clear_times"]["measurement_areas"]["in-front"] > 0
    if model == "sfm":
        cp = s["crowd_pressure"]
        assert set(cp) == {"max", "unit", "t", "x", "y"} and cp["unit"] == "1/s^2"
        assert cp["max"] > 0
        assert s["clear_times"]["start_areas"]["crowd"] == pytest.approx(ex["last"])
    else:
        assert s["crowd_pressure"] is None
        assert s["clear_times"]["start_areas"] == {"crowd": None}


@pytest.mark.parametrize("model", ["sfm", "eos"])
def test_pedmesh_run_records_safety_in_summary(geometries_dir, tmp_path, model):
    from pedmesh.cli import main
    from pedmesh.io.vtk import read_pvd_index

    out = tmp_path / model
    assert main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--model", model,
                 "--out", str(out), "-q"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "finished"
    _check_record(summary["safety"], model, 150)
    assert (out / "safety.vtu").is_file()
    assert len(read_pvd_index(out / "density.pvd")) == summary["frames"]  # frames as before
    # read back from the folder alone (the room file is found by its recorded hash)
    again = safety_measures(out)
    assert again == summary["safety"]
    if model == "eos":  # the same numbers from a run kept in memory
        import pedmesh

        mem = pedmesh.simulate(geometries_dir / "corridor_bottleneck.json", model=model)
        a, b = dict(mem.summary["safety"]), dict(summary["safety"])
        ea, eb = a.pop("exits")["end"], b.pop("exits")["end"]
        assert a == b
        assert ea == pytest.approx(eb, rel=1e-7)  # (outflow.csv holds 9 digits)


def test_safety_never_fails_a_run(geometries_dir, tmp_path, monkeypatch):
    import pedmesh.run.safety as RS
    from pedmesh.cli import main

    def broken(*args, **kwargs):
        raise RuntimeError("no luck")

    monkeypatch.setattr(RS, "safety_measures", broken)
    out = tmp_path / "run"
    assert main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--model", "eos",
                 "--out", str(out), "-q", "--t-end", "2"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "stopped at t_end"
    assert summary["safety"] == {"error": "RuntimeError: no luck"}
