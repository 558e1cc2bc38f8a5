"""Limits on inputs (issue 36): a crowd no room holds, a crowd too large to allocate, a
lognormal that overflows, a calibration file that is not text, a polygon on one line, an
empty sweep value, absurd export sizes. Each is refused in one line (exit status 2 on the
command line) that names the element, the parameter or the file and the limit, before
anything big is allocated. (The physical ranges of the model parameters are tested in
test_param_checks.py.)"""

from __future__ import annotations

import json

import numpy as np
import pytest

from pedmesh import ParameterError, PedmeshError
from pedmesh.cli import main
from pedmesh.errors import GeometryError, SimulationError
from pedmesh.geometry import Room, StartArea
from pedmesh.geometry.formats.native import room_from_dict


def _room(start: dict, w: float = 10.0, h: float = 5.0, **area) -> dict:
    """Room B of the issue: w x h m, a 1 m door, one start area 1 m inside the walls."""
    return {"name": "B", "outline": [[0, 0], [w, 0], [w, h], [0, h]],
            "exits": [{"name": "door", "polyline": [[w, h / 2 - 0.5], [w, h / 2 + 0.5]]}],
            "start_areas": [{"name": "crowd", "polygon": [[1, 1], [w - 1, 1], [w - 1, h - 1],
                                                          [1, h - 1]], **start, **area}]}


def _cli(capsys, *argv) -> tuple[int, list[str]]:
    status = main([str(a) for a in argv])
    return status, capsys.readouterr().err.strip().splitlines()


# ------------------------------------------------------------------ item 9: crowd limits
@pytest.mark.parametrize(("start", "w", "h", "message"), [
    ({"spacing": 1e-4}, 10, 5, "a spacing of 0.0001 m packs 1e+08 people per m^2, more than "
                               "the 10 /m^2 of the densest crowds (the spacing must be at "
                               "least 0.316 m)"),
    ({"density": 1e6}, 10, 5, "a density of 1e+06 /m^2 is more than the 10 /m^2"),
    ({"count": 10_000_000}, 5, 5, "10000000 people in 9 m^2 are 1.111e+06 /m^2, more than "
                                  "the 10 /m^2"),
])
@pytest.mark.parametrize("model", ["sfm", "eos"])
def test_a_start_area_denser_than_10_per_m2_is_refused(tmp_path, capsys, monkeypatch, start,
                                                        w, h, message, model):
    """spacing 1e-4 m ate 24 GB before the system killed it; density 1e6 and count 1e7 ended
    as 'internal error: MemoryError'; eos took 10 million people in 9 m^2. Now the room
    is refused when it is read, before a lattice or a mesh is made."""
    from pedmesh.geometry.room import StartArea as SA

    def no_lattice(*a, **k):
        raise AssertionError("a lattice was made")

    monkeypatch.setattr(SA, "lattice", no_lattice)
    path = tmp_path / "room.json"
    path.write_text(json.dumps(_room(start, w, h)))
    status, err = _cli(capsys, "run", path, "--model", model, "--out", tmp_path / "run", "-q")
    assert status == 2 and len(err) == 1, err
    assert f"start area 'crowd': {message}" in err[0]
    assert not (tmp_path / "run").exists()


def test_the_densest_allowed_start_areas_are_taken():
    square = [(0, 0), (10, 0), (10, 10), (0, 10)]
    assert StartArea("a", square, spacing=10 ** -0.5).expected_count == pytest.approx(1000)
    assert StartArea("a", square, density=10.0).expected_count == 1000
    assert StartArea("a", square, count=1000).expected_count == 1000
    StartArea("a", [(0, 0), (0.1, 0), (0.1, 0.1)], count=1)  # one person: any area
    with pytest.raises(GeometryError, match="1001 people in 100 m"):
        StartArea("a", square, count=1001)
    # an entrance's people arrive one by one: its count is not a density
    StartArea("gate", [(0, 0), (0.5, 0), (0.5, 0.5), (0, 0.5)], count=500,
              arrivals={"rate": 1.0})


def _big_room() -> Room:
    """1.25 million people at 5 /m^2 on 500 x 500 m (never meshed nor placed here)."""
    return room_from_dict(_room({"density": 5.0}, 502.0, 502.0))


@pytest.fixture
def nothing_big(monkeypatch):
    """Fails the test if a crowd is placed or a room meshed."""
    import sys

    import pedmesh.mesh as M
    from pedmesh.geometry.room import StartArea as SA

    def refuse(*a, **k):
        raise AssertionError("allocated before the crowd was checked")

    monkeypatch.setattr(SA, "lattice", refuse)
    for module in (sys.modules["pedmesh.mesh.triangulate"], M):
        monkeypatch.setattr(module, "triangulate", refuse)
    import pedmesh.mesh.site as S

    monkeypatch.setattr(S, "mesh_site", refuse)


def test_a_crowd_above_max_people_is_refused_before_anything_is_allocated(nothing_big,
                                                                          tmp_path, capsys):
    """The crowd's size comes from the areas (count, density x area, area / spacing^2);
    above the limit (1,000,000 by default) the run stops in one line naming --max-people,
    from the command line and from Python, before the mesh and the crowd are made."""
    import pedmesh

    room = _big_room()
    assert room.start_areas[0].expected_count == pytest.approx(1.25e6)
    path = tmp_path / "big.json"
    path.write_text(json.dumps(_room({"density": 5.0}, 502.0, 502.0)))
    for model in ("sfm", "eos"):
        status, err = _cli(capsys, "run", path, "--model", model, "--out", tmp_path / "run",
                           "-q")
        assert status == 2 and len(err) == 1, err
        assert ("the start areas hold about 1.25e+06 people, more than the limit of "
                "1,000,000; give --max-people N") in err[0]
        assert not (tmp_path / "run").exists()
    status, err = _cli(capsys, "run", path, "--max-people", "1000", "--out", tmp_path / "run",
                       "-q")
    assert status == 2 and "more than the limit of 1,000;" in err[0]
    status, err = _cli(capsys, "compare", path, "--models", "sfm,eos", "--out",
                       tmp_path / "cmp", "-q")
    assert status == 2 and len(err) == 1 and "--max-people N" in err[0]
    status, err = _cli(capsys, "ensemble", path, "--members", "1", "--out",
                       tmp_path / "ens", "-q")  # (on the client, before any cluster)
    assert status == 2 and len(err) == 1 and "--max-people N" in err[0], err
    assert not (tmp_path / "ens").exists()
    for call in (lambda: pedmesh.simulate(room, model="sfm"),
                 lambda: pedmesh.build(room, model="eos"),
                 lambda: pedmesh.simulate(path, model="rdue", max_people=10**6)):
        with pytest.raises(ParameterError, match=r"max_people=N in Python"):
            call()


def test_max_people_lets_a_crowd_through(load_shipped, tmp_path, capsys):
    """The limit is the user's to move, and the check stands in front of every run: the
    paper's Example 1 holds 2400 people."""
    import pedmesh
    from pedmesh.mesh import triangulate
    from pedmesh.run.driver import check_crowd, plan_run

    room = load_shipped("example1.json")
    assert check_crowd(room) == pytest.approx(2400)
    mesh = triangulate(room, max_area=20.0)
    with pytest.raises(ParameterError, match="more than the limit of 2,000"):
        plan_run(room, mesh, "rdue", max_people=2000)
    plan_run(room, mesh, "rdue", max_people=2400)
    run = pedmesh.build(room, model="sfm", mesh=mesh, max_people=2400)
    assert run.n_initial == 2400
    for bad in (0, -5, 2.5, True, "many"):
        with pytest.raises(ParameterError, match="max_people must be a positive whole number"):
            check_crowd(room, bad)


# ------------------------------------------------------------------ item 10: one-line errors
def test_a_lognormal_whose_median_overflows_is_refused(tmp_path, capsys):
    """Lognormal premovement with mu = 1000 ended as 'internal error: OverflowError'."""
    area = {"count": 20, "polygon": [[1, 1], [5, 1], [5, 4], [1, 4]],
            "premovement": {"distribution": "lognormal", "mu": 1000, "sigma": 1}}
    path = tmp_path / "room.json"
    path.write_text(json.dumps(_room({}, **area)))
    for model in ("sfm", "eos"):
        status, err = _cli(capsys, "run", path, "--model", model, "--out", tmp_path / "r",
                           "-q")
        assert status == 2 and len(err) == 1, err
        assert ("start area 'crowd': 'premovement': 'mu' must be in [-10, 10] (a median "
                "exp(mu) from 4.5e-05 to 22026), got 1000") in err[0]
    from pedmesh.population import distribution_from_spec

    for spec, what in (({"mu": -700.0, "sigma": 1.0}, "'mu' must be in"),
                       ({"mu": 1.0, "sigma": 1000.0}, r"'sigma' must be in \(0, 5\]"),
                       ({"mu": 1.0, "sigma": 1.0, "max": 3.0, "min": 800.0}, "'max' must")):
        with pytest.raises(GeometryError, match=what):
            distribution_from_spec({"distribution": "lognormal", **spec}, "premovement", "x")
    d = distribution_from_spec({"distribution": "lognormal", "mu": 10.0, "sigma": 5.0},
                               "premovement", "x")
    assert np.all(np.isfinite(d.sample(np.random.default_rng(0), 1000)))


def test_a_binary_calibration_file_is_one_line(geometries_dir, tmp_path, capsys):
    """--param calibration=<a binary file> ended as 'internal error: UnicodeDecodeError'."""
    binary = tmp_path / "eos.bin"
    binary.write_bytes(bytes(range(256)) * 8)
    room = geometries_dir / "l_shaped.json"
    for cal, message in ((binary, f"{binary}: not a calibration file (not UTF-8 text"),
                         (tmp_path, f"{tmp_path}: is a directory, not a calibration file")):
        status, err = _cli(capsys, "run", room, "--model", "eos", "--param",
                           f"calibration={cal}", "--out", tmp_path / "run", "-q",
                           "--max-area", "4")
        assert status == 2 and len(err) == 1 and message in err[0], err


# ------------------------------------------------------------------ item 11: blow-up advice
@pytest.mark.parametrize(("model", "params", "message"), [
    ("pw", {"c0": 1e300}, "parameter 'c0' = 1e+300 m/s is outside its physical range "
                          "[0, 10] m/s (or try a smaller CFL number"),
    ("mac2-local", {"gamma1": 1e300}, "parameter 'gamma1' = 1e+300 N m^4/(kg ped) is outside "
                                      "its physical range [0.001, 1000]"),
])
def test_a_blow_up_from_an_absurd_pressure_names_the_range(model, params, message):
    """pw c0 = 1e300 and mac2-local gamma1 = 1e300 said 'non-finite state ... try a smaller
    CFL number'. A run refuses them up front (test_param_checks.py); physics built directly
    (bounds only) that blows up names the parameter outside its range."""
    from pedmesh.mesh import triangulate
    from pedmesh.models.continuum.adapter import macro_model
    from pedmesh.models.continuum.solver import FVController, FVOptions, FVSolver, FVState

    room = room_from_dict(_room({"density": 2.0}, 4.0, 3.0))
    mesh = triangulate(room, max_area=0.2)
    solver = FVSolver(mesh, macro_model(model, **params), FVOptions(),
                      direction=lambda x, y: np.zeros(np.shape(x) + (2,)))
    c = mesh.centroids
    rho = 1.0 + np.exp(-((c[:, 0] - 1) ** 2 + (c[:, 1] - 1) ** 2))
    state = FVState(np.column_stack([rho, 0 * rho, 0 * rho]))
    controller = FVController(solver, state)
    with pytest.raises(SimulationError, match="non-finite state") as exc:
        while state.t < 1.0:
            controller.advance(1.0)
    assert message in str(exc.value)


# ------------------------------------------------------------------ item 13: smaller defects
@pytest.mark.parametrize("points", [
    [[0, 0], [1, 1], [2, 2]],
    [[0, 0], [2, 0], [1, 0], [3, 0]],
])
def test_a_polygon_on_one_line_says_so(tmp_path, capsys, points):
    """A start polygon of three collinear points was reported as 'the outline intersects
    itself'."""
    path = tmp_path / "room.json"
    path.write_text(json.dumps(_room({"count": 5}, polygon=points)))
    status, err = _cli(capsys, "run", path, "--out", tmp_path / "run", "-q")
    assert status == 2 and len(err) == 1, err
    assert (f"start area 'crowd': all {len(points)} points lie on one straight line, so the "
            f"polygon has zero area") in err[0]
    assert "intersects itself" not in err[0]
    with pytest.raises(GeometryError, match="obstacle 'o': all 3 points lie on one"):
        from pedmesh.geometry import Obstacle

        Obstacle("o", [(0, 0), (1, 1e-14), (2, 0)])
    with pytest.raises(GeometryError, match="intersects itself"):  # (a real bow tie)
        StartArea("bow", [(0, 0), (1, 1), (1, 0), (0, 1)], count=1)


def test_an_empty_sweep_value_is_refused():
    """--sweep U_f=1.0,,1.2 silently dropped the empty value."""
    from pedmesh.ensembles import parse_sweep

    assert parse_sweep(["U_f=1.0, 1.2"]) == {"U_f": [1.0, 1.2]}
    for item, message in (("U_f=1.0,,1.2", "--sweep U_f: value 2 of 3 is empty"),
                          ("U_f=1.0,1.2,", "--sweep U_f: value 3 of 3 is empty"),
                          ("U_f=,", "--sweep expects NAME=V1,V2"),
                          ("U_f=1.0,1e300", r"'U_f' must be in \[0.1, 5\] m/s, got 1e\+300")):
        with pytest.raises(ParameterError, match=message):
            parse_sweep([item])


def test_an_empty_sweep_value_is_one_line_on_the_command_line(geometries_dir, tmp_path,
                                                              capsys):
    status, err = _cli(capsys, "ensemble", geometries_dir / "l_shaped.json", "--sweep",
                       "U_f=1.0,,1.2", "--out", tmp_path / "ens", "-q")
    assert status == 2 and len(err) == 1 and "value 2 of 3 is empty" in err[0], err


# ------------------------------------------------------------------ item 7: export sizes
def test_export_refuses_absurd_sizes_and_times(geometries_dir, tmp_path, capsys):
    """export --wall-height 1e300 wrote infinite vertices; --time nan silently showed frame
    0."""
    room = geometries_dir / "l_shaped.json"
    out = tmp_path / "room.glb"
    for h in ("1e300", "nan", "0", "-2"):
        status, err = _cli(capsys, "export", room, "-o", out, "--wall-height", h)
        assert status == 2 and len(err) == 1, err
        assert "--wall-height must be a positive number of metres up to 1000" in err[0]
    assert not out.exists()
    for t in ("nan", "inf", "-1"):
        status, err = _cli(capsys, "export", room, "-o", out, "--run", tmp_path / "run",
                           "--time", t)
        assert status == 2 and len(err) == 1, err
        assert "--time must be a finite number of seconds >= 0" in err[0]
    from pedmesh.io import load_room
    from pedmesh.io.export3d import read_positions, room_scene

    with pytest.raises(PedmeshError, match="wall_height must be a positive number of metres "
                                           "up to 1000, got 1e"):
        room_scene(load_room(room), wall_height=1e300)
    with pytest.raises(PedmeshError, match="the time must be a finite number"):
        read_positions(tmp_path, float("nan"))
