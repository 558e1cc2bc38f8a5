"""The work around a run's steps done once, or not at all, with the same results: BLAS
limited once per run (FVController.stepping), the safety measures from the density frames
kept as they were written (pedmesh.run.safety.KeptDensity), the state before a step kept
without a copy, and the mesh refinement's distances remembered by point."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pedmesh import Room
from pedmesh.cli import main
from pedmesh.io import load_room
from pedmesh.mesh import triangulate


def _blas_threads() -> list:
    import scipy.linalg  # noqa: F401  (scipy's BLAS loaded, as the step loads it)
    from threadpoolctl import threadpool_info

    return sorted((i["filepath"], i["num_threads"]) for i in threadpool_info()
                  if i["user_api"] == "blas")


def test_a_run_limits_blas_once_and_gives_the_settings_back(geometries_dir, tmp_path,
                                                            monkeypatch):
    import numba

    from pedmesh.models.continuum import solver as S

    entered = []
    real = S._one_blas_thread

    def counted():
        entered.append(1)
        return real()

    monkeypatch.setattr(S, "_one_blas_thread", counted)
    blas, threads = _blas_threads(), numba.get_num_threads()
    out = tmp_path / "run"
    assert main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--model", "eos",
                 "--t-end", "3", "--out", str(out), "-q"]) == 0
    steps = json.loads((out / "summary.json").read_text())["steps"]
    assert steps > 5 and len(entered) == 1
    assert _blas_threads() == blas and numba.get_num_threads() == threads


def test_advance_alone_limits_blas_at_every_step(geometries_dir, monkeypatch):
    from pedmesh.models import get_model
    from pedmesh.models.continuum import solver as S

    room = load_room(geometries_dir / "corridor_bottleneck.json")
    run = get_model("eos").build(room, triangulate(room), {})
    entered = []
    real = S._one_blas_thread
    monkeypatch.setattr(S, "_one_blas_thread", lambda: (entered.append(1), real())[1])
    blas = _blas_threads()
    for _ in range(3):
        run.controller.advance()
    assert len(entered) == 3
    with run.stepping():
        with run.stepping():  # (nested: nothing more)
            for _ in range(3):
                run.controller.advance()
    assert len(entered) == 4 and _blas_threads() == blas


def test_the_safety_measures_from_the_kept_frames_are_those_of_the_files(
        geometries_dir, tmp_path, monkeypatch):
    """A continuum run's measures come from its density frames as it wrote them (no frame
    read back); the same from the files, and safety.vtu the same bytes."""
    import pedmesh.io.vtk as V
    from pedmesh.run.safety import KeptDensity, safety_measures

    reads = []
    real = V.read_vtu
    monkeypatch.setattr(V, "read_vtu", lambda *a, **k: (reads.append(1), real(*a, **k))[1])
    room_file = geometries_dir / "corridor_bottleneck.json"
    out = tmp_path / "run"
    assert main(["run", str(room_file), "--model", "eos", "--t-end", "30", "--out",
                 str(out), "-q"]) == 0
    assert reads == []
    summary = json.loads((out / "summary.json").read_text())
    assert summary["n_evacuated"] > 10
    vtu = (out / "safety.vtu").read_bytes()
    room = load_room(room_file)
    again = safety_measures(out, room, triangulate(room), n_initial=summary["n_initial"],
                            write_fields=True)
    assert len(reads) == summary["frames"] > 3
    assert again == summary["safety"] and (out / "safety.vtu").read_bytes() == vtu
    # frames that are not those of density.pvd are not used
    from pedmesh.run.results import RunResult

    frames = RunResult(out, summary).density_frames
    kept = KeptDensity()
    mesh = triangulate(room)
    for t, _ in frames[:-1]:
        kept.add(t, mesh, {"rho": np.zeros(mesh.n_triangles)})
    assert kept.matching(frames) is None
    kept.add(frames[-1][0] + 1.0, mesh, {"rho": np.zeros(mesh.n_triangles)})
    assert kept.matching(frames) is None
    small = KeptDensity(max_bytes=8 * mesh.n_triangles)
    small.add(0.0, mesh, {"rho": np.zeros(mesh.n_triangles)})
    small.add(1.0, mesh, {"rho": np.zeros(mesh.n_triangles)})
    assert small.frames is None and small.matching(frames) is None
    particle = KeptDensity()
    particle.add(0.0, mesh, None)
    assert particle.frames is None


def test_the_state_before_a_step_is_kept_also_while_everyone_waits():
    """The state before a step without a copy; while everyone is within their premovement
    (no step: the release changes the state in place) a copy, so that the frames between
    steps interpolate the state before the release."""
    from pedmesh.models import get_model

    room = Room(outline=[(0, 0), (30, 0), (30, 4), (0, 4)],
                exits=[{"name": "east", "polyline": [(30, 0), (30, 4)]}],
                start_areas=[{"name": "crowd", "polygon": [(12, 0), (18, 0), (18, 4), (12, 4)],
                              "spacing": 1.0,
                              "premovement": {"distribution": "uniform", "min": 0.2,
                                              "max": 3.0}}])
    run = get_model("eos").build(room, triangulate(room), {})
    waited = walked = 0
    while run.t < 5.0:
        before = run.state.Q.copy()
        t0 = run.t
        run.step()
        p_t, p_q = run._prev
        assert p_t == t0 and np.array_equal(p_q, before)
        assert np.array_equal(run.state_at(t0), before)
        if np.all(before[:, 0] == 0.0):
            waited += 1
            assert p_q is not run.state.Q
        else:
            walked += 1
    assert waited >= 1 and walked >= 3


def test_remembered_distances_are_the_searchs_own():
    from pedmesh.mesh.distance import SegmentDistance
    from pedmesh.mesh.triangulate import _NearestDistances

    rng = np.random.default_rng(4)
    corners = rng.uniform(0, 50, (7, 2))
    sets = (rng.uniform(0, 50, (40, 2, 2)), np.stack([corners, corners], axis=1),
            np.zeros((0, 2, 2)))
    memo = _NearestDistances(sets)
    a = rng.uniform(-5, 55, (300, 2))
    b = np.concatenate([a[100:250], rng.uniform(-5, 55, (200, 2)), a[:10], [[0.0, -0.0]]])
    for xy in (a, b, b[::-1], a[:0]):
        got = memo(xy)
        want = np.stack([SegmentDistance(s)(xy) for s in sets])
        assert got.shape == want.shape and np.array_equal(got, want)


def _geos_distances():
    """A size field's remembered distances, by GEOS instead of the compiled search."""
    from pedmesh.mesh.triangulate import _NearestDistances

    from geos_reference import geos_distance  # (tests/geos_reference.py)

    class Geos(_NearestDistances):
        def __call__(self, xy):
            xy = np.asarray(xy, float).reshape(-1, 2)
            return np.stack([geos_distance(t.seg, xy) for t in self.trees])

    return Geos


@pytest.mark.parametrize("name, options", [("example2.json", {}),
                                           ("pillar_hall.json", {"exit_size": 0.5}),
                                           ("l_shaped.json", {"feature_area": 0.1})])
def test_the_mesh_is_that_of_distances_computed_afresh(load_shipped, monkeypatch, name,
                                                       options):
    import importlib

    T = importlib.import_module("pedmesh.mesh.triangulate")
    room = load_shipped(name)
    m = T.triangulate(room, **options)

    # (and by GEOS, not the compiled search)
    monkeypatch.setattr(T, "_NearestDistances", _geos_distances())
    ref = T.triangulate(room, **options)
    assert np.array_equal(m.points, ref.points) and np.array_equal(m.triangles, ref.triangles)
    assert np.array_equal(m.segments, ref.segments)


def test_the_route_mesh_is_that_of_geos_distances(load_shipped, monkeypatch):
    """The route mesh (exits, reflex corners and walls in its size field) graded by the
    compiled distances is the one GEOS's nearest search grades, to the bit."""
    from collections import OrderedDict

    import pedmesh.mesh.route_mesh as RM

    room = load_shipped("pillar_hall.json")
    monkeypatch.setattr(RM, "_cache", OrderedDict())
    m = RM.route_mesh(room, resolution=0.3, kernel=2.0, clearance=0.5)

    monkeypatch.setattr(RM, "_NearestDistances", _geos_distances())
    monkeypatch.setattr(RM, "_cache", OrderedDict())
    ref = RM.route_mesh(room, resolution=0.3, kernel=2.0, clearance=0.5)
    assert ref is not m and len(RM.reflex_corners(room)) > 0
    assert np.array_equal(m.points, ref.points) and np.array_equal(m.triangles, ref.triangles)
