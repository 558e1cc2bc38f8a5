"""The Python API: simulate() in memory and into a folder, and the stepping form."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import pedmesh
from pedmesh.errors import ParameterError


def test_simulate_in_memory_matches_a_run_folder(geometries_dir, tmp_path):
    room = geometries_dir / "l_shaped.json"
    mem = pedmesh.simulate(room, model="rdue", preset="paper", mesh_options={"max_area": 4.0})
    disk = pedmesh.simulate(room, model="rdue", preset="paper", mesh_options={"max_area": 4.0},
                            out_dir=tmp_path / "run")
    assert mem.path is None and (tmp_path / "run" / "summary.json").is_file()
    assert mem.status == disk.status == "finished"
    for k in ("t_evac_50", "t_evac_90", "t_evac_100", "steps"):
        assert mem.summary[k] == disk.summary[k], k
    assert mem.times["T90"] == mem.summary["t_evac_90"]
    t, n = mem.evacuation
    td, nd = disk.evacuation
    assert len(t) == len(td) and np.allclose(t, td)
    assert np.allclose(n, nd, rtol=1e-5, atol=1e-5)  # (the CSV's 6 digits)
    assert n[-1] == pytest.approx(mem.summary["n_evacuated"])
    # the frames: every output interval, the cell density conserving the crowd
    assert len(mem.density) == disk.summary["frames"]
    ft, rho, vel = mem.density_at(0.0)
    assert ft == 0.0 and rho.min() >= 0.0 and vel.shape == (len(rho), 2)
    assert mem.density_fields_at(0.0)[2]["rho"].min() >= 0.0


def test_simulate_keeps_the_particle_models_trajectories(geometries_dir):
    r = pedmesh.simulate(geometries_dir / "l_shaped.json", model="sfm", preset="paper",
                         t_end=3.0, seed=1, mesh_options={"max_area": 4.0})
    assert r.status == "stopped at t_end" and r.frame_rate == 10.0
    n0 = r.summary["n_initial"]
    frames = np.unique(r.trajectories["frame"])
    assert frames[0] == 0 and frames[-1] == 30  # t = 0 ... 3 s at 10 frames/s
    assert np.sum(r.trajectories["frame"] == 0) == n0
    assert len(r.pedestrians) == 4  # t = 0, 1, 2, 3 s


def test_build_steps_a_model(geometries_dir):
    run = pedmesh.build(geometries_dir / "l_shaped.json", model="sfm", preset="paper",
                        mesh_options={"max_area": 4.0})
    x0 = run.sim.positions.copy()
    while run.t < 1.0 - 1e-9:
        run.step()
    assert run.t == pytest.approx(1.0) and run.remaining == run.n_initial
    assert np.linalg.norm(run.sim.positions - x0, axis=1).max() > 0.1  # they walk


def test_api_errors_are_clear(geometries_dir):
    with pytest.raises(ParameterError, match="room must be a Room, a Building or the path"):
        pedmesh.simulate(42)
    with pytest.raises(ParameterError, match="unknown model 'sfn'"):
        pedmesh.build(geometries_dir / "l_shaped.json", model="sfn")
    with pytest.raises(ParameterError, match="takes no option 'seed'"):
        pedmesh.build(geometries_dir / "l_shaped.json", model="eos", seed=1)


def test_a_run_can_skip_the_safety_measures(geometries_dir, tmp_path):
    """Scratch measurement runs (calibrations) skip the crowd-safety step; the run is the
    same."""
    import json

    from pedmesh.io import load_room
    from pedmesh.mesh import triangulate
    from pedmesh.run import run_model

    room = load_room(geometries_dir / "l_shaped.json")
    mesh = triangulate(room, max_area=4.0)
    a = run_model(room, mesh, "rdue", out_dir=tmp_path / "a", quiet=True, preset="paper")
    b = run_model(room, mesh, "rdue", out_dir=tmp_path / "b", quiet=True, preset="paper",
                  safety=False)
    assert "safety" in a and "safety" not in b and not (tmp_path / "b" / "safety.vtu").exists()
    assert json.loads((tmp_path / "b" / "summary.json").read_text())["t_evac_90"] == \
        a["t_evac_90"]


def test_the_api_takes_a_building():
    """pedmesh.build and pedmesh.simulate take a building (its file or the object): one
    surface mesh of its levels and stairs."""
    import pedmesh
    from pedmesh.io import load_room
    from pedmesh.mesh.surface import SurfaceMesh

    office = Path(__file__).resolve().parents[2] / "geometries" / "office.json"
    run = pedmesh.build(load_room(office), "eos", mesh_options={"max_area": 4.0})
    assert isinstance(run.mesh, SurfaceMesh) and len(run.mesh.pieces) == 13
    res = pedmesh.simulate(office, "sfm", t_end=1.0, mesh_options={"max_area": 4.0})
    assert res.summary["n_initial"] == 300
    tr = res.trajectories  # (in memory: with the height and the level or stair)
    assert set(tr["place"]) >= {"ground", "fourth"} and tr["z"].max() == pytest.approx(14.0)
    with pytest.raises(pedmesh.PedmeshError, match="exit_size"):
        pedmesh.build(office, "eos", mesh_options={"exit_size": 0.2})
