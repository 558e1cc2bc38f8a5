"""The command line, called through main([...])."""

from __future__ import annotations

import subprocess
import time
import sys

import meshio
import numpy as np
import pytest

from pedmesh.cli import main


def test_mesh_command_summary_and_vtu(geometries_dir, tmp_path, capsys):
    out = tmp_path / "sub" / "ex3.vtu"
    assert main(["mesh", str(geometries_dir / "example3.json"), "--max-area", "2", "-o",
                 str(out)]) == 0
    text = capsys.readouterr().out
    for part in ("vertices", "triangles", "smallest", "exit-south 10.000 m", "exit-north 10.000 m",
                 "4800.000 m^2", "2400 in 1 start area"):
        assert part in text
    m = meshio.read(out)
    assert set(np.unique(m.cell_data_dict["boundary_kind"]["line"])) == {1, 2, 3}


def test_mesh_rejects_non_vtu_output(geometries_dir, tmp_path, capsys):
    assert main(["mesh", str(geometries_dir / "l_shaped.json"), "-o", str(tmp_path / "m.txt")]) == 2
    assert "use a .vtu suffix" in capsys.readouterr().err


def test_bad_mesh_option_is_one_line(geometries_dir, capsys):
    assert main(["mesh", str(geometries_dir / "l_shaped.json"), "--max-area", "-3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "max_area" in err[0]


@pytest.mark.parametrize("args", [["--help"], ["mesh", "--help"], ["calibrate", "--help"],
                                  ["compare", "--help"]])
def test_help(args, capsys):
    with pytest.raises(SystemExit) as info:
        main(args)
    assert info.value.code == 0
    assert "usage: pedmesh" in capsys.readouterr().out


def test_console_script_runs(geometries_dir):
    r = subprocess.run([sys.executable, "-m", "pedmesh", "mesh", str(geometries_dir / "nope.json")],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.strip() == f"pedmesh: error: {geometries_dir / 'nope.json'}: no such file"


def test_route_command(geometries_dir, tmp_path, capsys):
    out = tmp_path / "route.vtu"
    assert main(["route", str(geometries_dir / "example3.json"), "--max-area", "2", "-o",
                 str(out)]) == 0
    text = capsys.readouterr().out
    assert "solve" in text and "distance to exit" in text
    m = meshio.read(out)
    assert m.point_data["phi"].min() == 0.0
    assert 100 < m.point_data["phi"].max() < 102  # far corner (0, 0 or 50): about 100.5 m
    d = m.point_data["direction"]
    np.testing.assert_allclose(np.hypot(d[:, 0], d[:, 1]), 1.0, atol=1e-12)


def test_route_unknown_exit(geometries_dir, tmp_path, capsys):
    assert main(["route", str(geometries_dir / "example3.json"), "--exits", "exit-west",
                 "-o", str(tmp_path / "r.vtu")]) == 2
    assert "unknown exit 'exit-west'" in capsys.readouterr().err


def test_run_command_writes_the_contract(geometries_dir, tmp_path, capsys):
    import json

    import pyvista as pv

    out = tmp_path / "cb"
    assert main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--model", "sfm",
                 "--out", str(out), "-q", "--param", "output_interval=5"]) == 0
    text = capsys.readouterr().out
    assert "150 of 150 out (finished)" in text
    s = json.loads((out / "summary.json").read_text())
    for key in ("model", "n_initial", "n_evacuated", "t_evac_50", "t_evac_90", "t_evac_100",
                "steps", "dt", "wall_time_s", "parameters"):
        assert key in s
    assert s["model"] == "sfm" and s["n_evacuated"] == 150 and s["status"] == "finished"
    from pedmesh.presets import get_preset

    A = get_preset("validated").values["A"].value  # the default preset's
    assert s["parameters"]["A"] == A and s["parameters"]["output_interval"] == 5.0
    assert s["t_evac_50"] < s["t_evac_90"] < s["t_evac_100"]
    rows = (out / "evacuation.csv").read_text().splitlines()
    assert rows[0] == "t,evacuated"
    t = np.array([float(r.split(",")[0]) for r in rows[1:]])
    n = np.array([float(r.split(",")[1]) for r in rows[1:]])
    assert np.diff(t).max() <= 0.5 + 1e-9 and n[-1] == 150 and np.all(np.diff(n) >= 0)
    reader = pv.PVDReader(out / "pedestrians.pvd")
    reader.set_active_time_value(reader.time_values[1])
    cloud = reader.read()[0]
    assert {"velocity", "speed", "density"} <= set(cloud.point_data.keys())
    dens = pv.PVDReader(out / "density.pvd")
    dens.set_active_time_value(dens.time_values[0])
    assert dens.read()[0].point_data["density"].max() > 1.0
    traj = (out / "trajectories.txt").read_text().splitlines()
    assert any("framerate: 10 fps" in line for line in traj[:4])  # own rate, not the frames'


def test_trajectories_load_in_pedpy(geometries_dir, tmp_path):
    pedpy = pytest.importorskip("pedpy")
    out = tmp_path / "cb"
    assert main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--out", str(out),
                 "-q", "--t-end", "5", "--trajectory-rate", "4"]) == 0
    traj = pedpy.load_trajectory_from_txt(trajectory_file=out / "trajectories.txt")
    assert traj.frame_rate == 4.0
    assert len(traj.data) == 150 * 21 and set(traj.data.columns) >= {"id", "frame", "x", "y"}


@pytest.mark.parametrize(("args", "message"), [
    (["--param", "foo=1"], "unknown parameter 'foo'"),
    (["--param", "dt=abc"], "parameter 'dt': 'abc' is not a number"),
    (["--param", "dt"], "--param expects NAME=VALUE, got 'dt'"),
    (["--param", "tau=-1"], "parameter 'tau' must be in [0.05, 100] s, got -1.0"),
    (["--model", "nope"], "unknown model 'nope'"),
    (["--t-end", "-5"], "t_end must be a positive number"),
])
def test_run_bad_arguments_are_one_line(geometries_dir, tmp_path, capsys, args, message):
    status = main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--out",
                   str(tmp_path / "x"), "-q", *args])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2
    assert len(err) == 1 and message in err[0], err


def test_run_survives_sigterm(geometries_dir, tmp_path):
    import json
    import signal
    import time

    out = tmp_path / "ex2"
    proc = subprocess.Popen([sys.executable, "-m", "pedmesh", "run",
                             str(geometries_dir / "example2.json"), "--out", str(out), "-q"],
                            stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    csv = out / "evacuation.csv"
    deadline = time.time() + 180
    while time.time() < deadline:
        if csv.exists() and len(csv.read_text().splitlines()) > 25:
            break
        time.sleep(0.2)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130
    assert len(err.strip().splitlines()) == 1 and "interrupted at t =" in err
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "interrupted" and s["t_stop"] >= 2.4
    assert len(csv.read_text().splitlines()) > 25


def test_calibrate_command(tmp_path, capsys):
    out = tmp_path / "eos.json"
    assert main(["calibrate", "--densities", "1,4", "--n", "120", "--replicas", "2",
                 "--relax-time", "1", "--sample-time", "1", "--param", "A=1500", "-o",
                 str(out), "-q"]) == 0
    from pedmesh.calibration import load_eos

    cal = load_eos(out)
    assert cal["parameters"]["A"] == 1500.0 and len(cal["table"]) == 2
    assert "written to" in capsys.readouterr().out


@pytest.mark.parametrize("args, message", [
    (["--param", "v0=2"], "irrelevant parameter 'v0'"),
    (["--densities", "1,x"], "--densities expects numbers"),
    (["--densities", "1,12", "--n", "50"], "narrower than 3 cut-offs"),
    (["--dt", "-1"], "'dt' must be positive"),
])
def test_calibrate_bad_arguments_are_one_line(tmp_path, capsys, args, message):
    assert main(["calibrate", "-o", str(tmp_path / "e.json"), *args]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_run_seed_gives_another_realisation_and_the_same_twice(tmp_path, geometries_dir):
    """Issue 46: `pedmesh run --seed N`."""
    import json

    room = geometries_dir / "corridor_bottleneck.json"

    def traj(seed, name):
        out = tmp_path / name
        args = ["run", str(room), "--out", str(out), "-q", "--t-end", "3"]
        assert main(args + (["--seed", str(seed)] if seed is not None else [])) == 0
        s = json.loads((out / "summary.json").read_text())
        return (out / "trajectories.txt").read_text(), s["parameters"]["seed"]

    a, sa = traj(3, "a")
    b, _ = traj(3, "b")
    c, sc = traj(0, "c")
    assert sa == 3 and sc == 0 and a == b and a != c
    assert main(["run", str(room), "--model", "eos", "--seed", "1", "--out",
                 str(tmp_path / "e"), "-q"]) == 2


def test_the_progress_bar_counts_people(tmp_path, geometries_dir, capsys):
    """Issue 46: progress as people out of all of them, the simulated time beside it."""
    assert main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--out",
                 str(tmp_path / "r"), "--t-end", "30"]) == 0
    err = capsys.readouterr().err.replace("\r", "\n")
    last = [ln for ln in err.splitlines() if " out " in ln][-1]
    # stopped at t_end with people inside: the bar says how many are out, not 100 %
    assert "/150 out" in last and "t=30.0/30 s" in last and "100%" not in last


def test_a_first_run_says_it_compiles(tmp_path, geometries_dir, capsys, monkeypatch):
    """Issue 46: a one-line notice while the kernels compile (here: as if the cache were
    empty), none once they are cached."""
    import pedmesh.cli.cmd_run as R

    room = str(geometries_dir / "corridor_bottleneck.json")
    assert main(["run", room, "--out", str(tmp_path / "a0"), "--t-end", "1", "-q"]) == 0
    assert R.kernels_compiled(True)  # (cached now, if not before)
    assert main(["run", room, "--out", str(tmp_path / "a"), "--t-end", "1"]) == 0
    assert "compiling" not in capsys.readouterr().err
    monkeypatch.setattr(R, "kernels_compiled", lambda particle: False)
    assert main(["run", room, "--out", str(tmp_path / "b"), "--t-end", "1"]) == 0
    err = capsys.readouterr().err
    assert err.startswith("pedmesh: compiling the numerical kernels")


def test_a_room_file_pins_the_seed(tmp_path, geometries_dir):
    """Issue 46: `"seed"` in a room file is the seed of its particle runs unless --seed
    says otherwise; the continuum models ignore it."""
    import json

    data = json.loads((geometries_dir / "corridor_bottleneck.json").read_text())
    room = tmp_path / "room.json"

    def run(seed_in_file, args, name):
        room.write_text(json.dumps({**data, **({"seed": seed_in_file}
                                               if seed_in_file is not None else {})}))
        out = tmp_path / name
        assert main(["run", str(room), "--out", str(out), "--t-end", "2", "-q", *args]) == 0
        s = json.loads((out / "summary.json").read_text())
        return s["parameters"]["seed"], (out / "trajectories.txt").read_text()

    seed, pinned = run(3, [], "pinned")
    assert seed == 3
    assert run(None, ["--seed", "3"], "given")[1] == pinned  # the same realisation
    told = run(3, ["--seed", "0"], "told")
    assert told[0] == 0 and told[1] != pinned  # --seed wins
    assert run(None, [], "default")[0] is None  # (no seed anywhere: the plain lattice)
    room.write_text(json.dumps({**data, "seed": 3}))
    assert main(["run", str(room), "--model", "eos", "--out", str(tmp_path / "eos"),
                 "--t-end", "1", "-q"]) == 0
    bad = {**data, "seed": -1}
    room.write_text(json.dumps(bad))
    assert main(["run", str(room), "--out", str(tmp_path / "bad"), "-q"]) == 2


def test_a_fresh_install_says_it_compiles_within_two_seconds(tmp_path, geometries_dir):
    """Issue 46: with an empty numba cache (a fresh install), `pedmesh run` prints the
    compile notice within 2 s of its start (the process is stopped there: the compilation
    itself takes minutes)."""
    import os
    import threading

    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba-cache"))
    cmd = [sys.executable, "-m", "pedmesh", "run",
           str(geometries_dir / "corridor_bottleneck.json"), "--t-end", "0.5",
           "--out", str(tmp_path / "run")]
    lines: list[tuple[float, str]] = []
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL,
                            text=True, env=env)

    def read() -> None:
        for line in proc.stderr:
            lines.append((time.perf_counter() - t0, line))

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        deadline = time.perf_counter() + 60
        while not lines and proc.poll() is None and time.perf_counter() < deadline:
            time.sleep(0.01)
    finally:
        proc.kill()
        proc.wait()
    assert lines, "nothing printed"
    when, first = lines[0]
    assert first.startswith("pedmesh: compiling the numerical kernels"), first
    assert when < 2.0, f"the notice came after {when:.2f} s"
