"""What a run writes and how it owns its directory: outflow from exit crossings,
trajectories at their own rate ending on the exit, JuPedSim's SQLite, stale files, locks,
failures and the settings that `compare` checks."""

from __future__ import annotations

import csv
import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from pedmesh.cli import main
from pedmesh.run.output import RunWriter, run_status
from pedmesh.mesh import triangulate

FAST_GEOMETRIES = ["corridor_bottleneck.json", "l_shaped.json", "pillar_hall.json", "foyer.svg"]
ALL_GEOMETRIES = FAST_GEOMETRIES + ["example1.json", "example2.json", "example3.json"]


def _exits_rows(out: Path) -> list[list[str]]:
    with open(out / "exits.csv", newline="") as f:
        return list(csv.reader(f))[1:]


def _exits_csv(out: Path) -> dict[str, int]:
    counts: dict[str, int] = {}
    for row in _exits_rows(out):
        name = row[1]
        counts[name] = counts.get(name, 0) + 1
    return counts


def _outflow_integrals(out: Path) -> dict[str, float]:
    """Each exit's outflow.csv integrated over time (flow x the interval it covers)."""
    names = (out / "outflow.csv").read_text().splitlines()[0].split(",")[1:]
    d = np.loadtxt(out / "outflow.csv", delimiter=",", skiprows=1, ndmin=2)
    dt = np.diff(d[:, 0])
    return {n: float(np.sum(d[1:, 1 + k] * dt)) for k, n in enumerate(names)}


def _check_sfm_outputs(out: Path, room) -> None:
    pedpy = pytest.importorskip("pedpy")
    s = json.loads((out / "summary.json").read_text())
    counts = _exits_csv(out)
    assert sum(counts.values()) == s["n_evacuated"] == s["n_initial"]
    # outflow.csv integrates to each exit's count (the issue asks for 2 %)
    integ = _outflow_integrals(out)
    for name, c in counts.items():
        assert abs(integ[name] - c) <= 0.02 * c, (name, integ[name], c)
    # trajectories: 10 frames/s by default, in both files, same frames and ids
    txt = pedpy.load_trajectory_from_txt(trajectory_file=out / "trajectories.txt")
    sql = pedpy.load_trajectory_from_jupedsim_sqlite(trajectory_file=out / "trajectories.sqlite")
    assert txt.frame_rate == sql.frame_rate == 10.0
    a = txt.data.sort_values(["frame", "id"])[["id", "frame", "x", "y"]].to_numpy()
    b = sql.data.sort_values(["frame", "id"])[["id", "frame", "x", "y"]].to_numpy()
    assert a.shape == b.shape and np.array_equal(a[:, :2], b[:, :2])
    assert np.abs(a[:, 2:] - b[:, 2:]).max() < 1e-4  # the text file has 4 decimals
    area = pedpy.load_walkable_area_from_jupedsim_sqlite(trajectory_file=out
                                                         / "trajectories.sqlite")
    assert area.polygon.area == pytest.approx(room.area, rel=1e-9)
    # every leaver's last row is on the exit they took
    import shapely

    data = txt.data.sort_values("frame")
    last = data.groupby("id").tail(1).set_index("id")
    exit_of = {}
    for i, name, _ in _exits_rows(out):
        exit_of[int(i)] = name
    lines = {e.name: shapely.LineString(room.exit_polyline(k)) for k, e in enumerate(room.exits)}
    for i, name in exit_of.items():
        p = shapely.Point(last.loc[i, "x"], last.loc[i, "y"])
        assert lines[name].distance(p) < 2e-4, (i, name)
    # PedPy's count at a line at the exits equals exits.csv. PedPy does not count a movement
    # that ends on its line and leaves out each trajectory's last movement, so each exit's
    # line stands 0.3 m inside it (more than anyone walks in one frame, 0.1 s), across the
    # whole room there (people hugging the wall reach the exit from the side). Exits on one
    # wall share a line.
    gates: dict[tuple, list[str]] = {}
    for k, e in enumerate(room.exits):
        pl = np.asarray(room.exit_polyline(k), float)
        assert len(pl) == 2  # the shipped exits are straight
        d = (pl[1] - pl[0]) / np.hypot(*(pl[1] - pl[0]))
        normal = np.array([-d[1], d[0]])
        mid = 0.5 * (pl[0] + pl[1])
        if not room.walkable.contains(shapely.Point(*(mid + 0.05 * normal))):
            normal = -normal
        far = 1e3 * d
        across = shapely.LineString([mid - far + 0.3 * normal, mid + far + 0.3 * normal])
        pieces = across.intersection(room.walkable)
        pieces = getattr(pieces, "geoms", [pieces])
        gate = min(pieces, key=lambda g: g.distance(shapely.Point(*mid)))
        key = tuple(np.round(np.asarray(gate.coords), 6).ravel())
        gates.setdefault(key, []).append(e.name)
    for key, names in gates.items():
        line = pedpy.MeasurementLine(np.reshape(key, (2, 2)))
        nt, _ = pedpy.compute_n_t(traj_data=txt, measurement_line=line)
        assert int(nt.cumulative_pedestrians.max()) == sum(counts.get(n, 0) for n in names)


@pytest.mark.parametrize("geometry", FAST_GEOMETRIES)
def test_sfm_outflow_and_trajectories(geometries_dir, load_shipped, tmp_path, geometry):
    out = tmp_path / "run"
    assert main(["run", str(geometries_dir / geometry), "--out", str(out), "-q"]) == 0
    _check_sfm_outputs(out, load_shipped(geometry))


@pytest.mark.slow
@pytest.mark.parametrize("geometry", ALL_GEOMETRIES)
def test_sfm_outflow_and_trajectories_every_shipped_room(geometries_dir, load_shipped, tmp_path,
                                                         geometry):
    out = tmp_path / "run"
    assert main(["run", str(geometries_dir / geometry), "--out", str(out), "-q"]) == 0
    _check_sfm_outputs(out, load_shipped(geometry))


def test_continuum_outflow_integrates_to_the_evacuated(geometries_dir, tmp_path):
    out = tmp_path / "rdue"
    assert main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--model", "rdue",
                 "--out", str(out), "-q", "--t-end", "30"]) == 0
    s = json.loads((out / "summary.json").read_text())
    integ = _outflow_integrals(out)
    assert sum(integ.values()) == pytest.approx(s["n_evacuated"], rel=1e-7)  # 9 digits a row
    assert s["n_evacuated"] > 10


def test_rerun_leaves_no_stale_files(geometries_dir, tmp_path):
    out = tmp_path / "run"
    room = str(geometries_dir / "corridor_bottleneck.json")
    assert main(["run", room, "--out", str(out), "-q", "--t-end", "3"]) == 0
    for name in ("exits.csv", "pedestrians.pvd", "pedestrians", "trajectories.txt",
                 "trajectories.sqlite", "outflow_kernel.csv"):
        assert (out / name).exists()
    (out / "notes.txt").write_text("mine")  # not a run file: it stays
    assert main(["run", room, "--model", "rdue", "--out", str(out), "-q", "--t-end", "3"]) == 0
    for name in ("exits.csv", "pedestrians.pvd", "pedestrians", "trajectories.txt",
                 "trajectories.sqlite", "outflow_kernel.csv"):
        assert not (out / name).exists(), name
    assert (out / "notes.txt").read_text() == "mine"
    assert json.loads((out / "summary.json").read_text())["model"] == "rdue"
    frames = sorted((out / "density").iterdir())
    assert len(frames) == 4  # t = 0, 1, 2, 3 s of this run only


def test_refuses_a_folder_that_is_not_a_run(geometries_dir, tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("precious")
    status = main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--out", str(out),
                   "-q", "--t-end", "1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and "not a pedmesh run directory" in err[0]
    assert sorted(p.name for p in out.iterdir()) == ["thesis.tex"]  # no .lock left


def test_second_run_into_a_busy_folder_is_refused(geometries_dir, tmp_path, capsys):
    out = tmp_path / "busy"
    first = RunWriter(out, {"model": "sfm"})  # a run in progress holds the lock
    try:
        status = main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--out",
                       str(out), "-q", "--t-end", "1"])
        err = capsys.readouterr().err.strip().splitlines()
        assert status == 2 and len(err) == 1 and "another pedmesh run is writing" in err[0]
        assert json.loads((out / "summary.json").read_text())["status"] == "running"
        assert run_status(out) == "running"  # the lock is held: it really runs
    finally:
        first.finish(status="finished")
    assert run_status(out) == "finished"


def test_setup_failure_is_recorded(geometries_dir, tmp_path, capsys):
    out = tmp_path / "run"
    room = str(geometries_dir / "corridor_bottleneck.json")
    assert main(["run", room, "--out", str(out), "-q", "--t-end", "1"]) == 0
    status = main(["run", room, "--model", "eos", "--out", str(out), "-q",
                   "--param", f"calibration={tmp_path / 'missing.json'}"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and "no such calibration file" in err[0]
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "failed" and "no such calibration file" in s["error"]
    assert s["model"] == "eos"


def test_full_disk_is_a_failure_without_part_files(geometries_dir, tmp_path, monkeypatch):
    import pedmesh
    from pedmesh.run import run_model

    calls = {"n": 0}
    original = RunWriter.trajectory_frame

    def filling_up(self, *args, **kwargs):
        calls["n"] += 1
        if calls["n"] > 5:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), "trajectories.txt")
        return original(self, *args, **kwargs)

    monkeypatch.setattr(RunWriter, "trajectory_frame", filling_up)
    room = pedmesh.load_room(geometries_dir / "corridor_bottleneck.json")
    out = tmp_path / "full"
    with pytest.raises(OSError) as info:
        run_model(room, triangulate(room), "sfm", out_dir=out, quiet=True, t_end=5.0)
    assert info.value.errno == errno.ENOSPC
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "failed" and "No space left" in s["error"]
    assert not list(out.rglob("*.part"))
    assert run_status(out) == "failed"


def test_killed_run_reads_as_interrupted(geometries_dir, tmp_path):
    from pedmesh.run import RunResult

    out = tmp_path / "killed"
    proc = subprocess.Popen([sys.executable, "-m", "pedmesh", "run",
                             str(geometries_dir / "example2.json"), "--out", str(out), "-q"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    csv = out / "evacuation.csv"
    deadline = time.time() + 180
    while time.time() < deadline and not (csv.exists() and len(csv.read_text().splitlines()) > 5):
        time.sleep(0.2)
    assert run_status(out) == "running"
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    assert json.loads((out / "summary.json").read_text())["status"] == "running"  # as left
    assert run_status(out) == "interrupted"
    assert RunResult.load(out).status == "interrupted" and not RunResult.load(out).finished


def test_compare_reruns_when_settings_differ(geometries_dir, tmp_path, capsys):
    room = str(geometries_dir / "corridor_bottleneck.json")
    out = tmp_path / "cmp"
    base = ["compare", room, "--models", "sfm", "--out", str(out)]
    assert main([*base, "--t-end", "2"]) == 0
    assert "running (no run there yet)" in capsys.readouterr().err
    assert main([*base, "--t-end", "2"]) == 0
    assert "reusing the finished run" in capsys.readouterr().err
    assert main([*base, "--t-end", "3"]) == 0
    err = capsys.readouterr().err
    assert "running (t_end differs (2.0 there, 3.0 asked))" in err
    assert json.loads((out / "sfm" / "summary.json").read_text())["t_end"] == 3.0
    # the same command on another room file with the same name: a different hash
    other = tmp_path / "corridor_bottleneck.json"
    text = json.loads(Path(room).read_text())
    text["name"] = "changed"
    other.write_text(json.dumps(text))
    assert main(["compare", str(other), "--models", "sfm", "--out", str(out),
                 "--t-end", "3"]) == 0
    assert "room_sha256 differs" in capsys.readouterr().err


@pytest.mark.parametrize("dense", [0, 1])
@pytest.mark.parametrize("model", ["rdue", "pw"])
def test_continuum_frames_at_the_requested_times(geometries_dir, tmp_path, model, dense):
    from pedmesh.io import read_pvd_index

    out = tmp_path / model
    assert main(["run", str(geometries_dir / "l_shaped.json"), "--model", model, "--out",
                 str(out), "-q", "--t-end", "4.5", "--param", "output_interval=0.5",
                 "--param", f"dense_frames={dense}", "--max-area", "2"]) == 0
    times = [t for t, _ in read_pvd_index(out / "density.pvd")]
    assert times == [0.5 * k for k in range(10)]  # exactly, the last one at t_end
    s = json.loads((out / "summary.json").read_text())
    assert s["t_stop"] == 4.5 and s["mass_error_max"] < 1e-12


def test_step_limit_lands_exactly_and_never_overshoots(load_shipped):
    from pedmesh.models.continuum.adapter import MacroRun
    from pedmesh.models import get_model

    room = load_shipped("l_shaped.json")
    mesh = triangulate(room, max_area=2.0)
    run = get_model("pw").build(room, mesh, {})
    ref = get_model("pw").build(room, mesh, {})
    assert isinstance(run, MacroRun)
    targets = [0.37, 0.5, 1.0, 1.01, 2.0]
    for target in targets:
        while run.t < target:
            before = run.t
            run.step(target)
            assert before < run.t <= target
        assert run.t == target
    for _ in range(5):  # without a limit: the CFL step, as before
        ref.step()
    assert ref.t > 0.37 and abs(ref.remaining + ref.evacuated - ref.n_initial) < 1e-9


def test_dense_frames_interpolate_the_states_around_them(geometries_dir, tmp_path):
    """Interpolated frames: the states at the step's ends at its ends, their convex
    combination in between (mass linear in t, rho >= 0); and the frames of a free-running
    run close to those of a run whose steps land on the frame times."""
    import pyvista as pv

    from pedmesh.io import read_pvd_index
    from pedmesh.io.rooms import load_room
    from pedmesh.models import get_model

    room = load_room(geometries_dir / "l_shaped.json")
    mesh = triangulate(room, max_area=2.0)
    run = get_model("eos").build(room, mesh, {})
    for _ in range(3):
        run.step()
    t0, Q0 = run._prev
    t1, Q1 = run.t, run.state.Q
    assert t0 < t1
    assert np.array_equal(run.state_at(t1), Q1) and np.array_equal(run.state_at(t0), Q0)
    mid = run.state_at(0.5 * (t0 + t1))
    assert np.allclose(mid, 0.5 * (Q0 + Q1), rtol=1e-14, atol=1e-300)
    assert mid[:, 0].min() >= 0.0
    m0, m1, mm = (run.solver.mass(q) for q in (Q0, Q1, mid))
    assert abs(mm - 0.5 * (m0 + m1)) < 1e-12 * m0
    with pytest.raises(ValueError, match="not within the last step"):
        run.state_at(t0 - 1.0)

    rho = {}
    for dense in (0, 1):
        out = tmp_path / f"d{dense}"
        assert main(["run", str(geometries_dir / "l_shaped.json"), "--model", "eos", "--out",
                     str(out), "-q", "--t-end", "6", "--param", f"dense_frames={dense}",
                     "--max-area", "2", "--preset", "paper"]) == 0
        index = read_pvd_index(out / "density.pvd")
        assert [t for t, _ in index] == [float(k) for k in range(7)]
        rho[dense] = [pv.read(f).cell_data["rho"] for _, f in index]
    for a, b in zip(rho[0], rho[1]):
        # L1: measured under 0.2 % with the paper's parameters. (The two runs take different
        # steps, so this also holds the difference of their own time errors, which grows
        # with the dynamics: 1.6 % by 6 s under the validated preset's tau = 0.3 s. The
        # interpolation itself is checked exactly above.)
        assert np.abs(a - b).sum() <= 0.01 * a.sum()
