"""Ensembles on Dask: a real scheduler and worker started as processes on 127.0.0.1, the
default LocalCluster, failures, resuming, seeds."""

from __future__ import annotations

import json
import subprocess
import sys
import time

import numpy as np
import pytest

pytest.importorskip("distributed")
pd = pytest.importorskip("pandas")

from pedmesh.cli import main  # noqa: E402
from pedmesh.ensembles import EnsembleError, ensemble, member_seeds  # noqa: E402

ROOM = "l_shaped.json"


@pytest.fixture(scope="module")
def client():
    """A LocalCluster of two single-threaded worker processes, shared by the tests here."""
    from distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           host="127.0.0.1", dashboard_address=None)
    c = Client(cluster)
    yield c
    c.close()
    cluster.close()


@pytest.fixture
def dask_cluster_processes(tmp_path):
    """`dask scheduler` and one `dask worker` as real processes on 127.0.0.1; yields
    (scheduler address, worker address); both are stopped afterwards."""
    from distributed import Client

    sched_file = tmp_path / "scheduler.json"
    procs = []
    try:
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", "0",
             "--no-dashboard", "--scheduler-file", str(sched_file)],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        deadline = time.time() + 60
        info = None
        while info is None and time.time() < deadline:  # the file is written, not renamed
            try:
                info = json.loads(sched_file.read_text())
            except (OSError, ValueError):
                time.sleep(0.1)
        assert info is not None, "the dask scheduler did not start"
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "dask", "worker", "--scheduler-file", str(sched_file),
             "--host", "127.0.0.1", "--nthreads", "1", "--nworkers", "1", "--no-dashboard"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        address = info["address"]
        assert address.startswith("tcp://127.0.0.1:")
        with Client(address, timeout="30s") as c:
            c.wait_for_workers(1, timeout=90)
            workers = list(c.scheduler_info()["workers"])
        assert len(workers) == 1
        yield address, workers[0]
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()


def test_member_seeds_are_reproducible_and_distinct():
    a, b = member_seeds(7, 5), member_seeds(7, 5)
    assert a == b and len(set(a)) == 5
    assert member_seeds(8, 5) != a
    assert member_seeds(7, 3) == a[:3]  # adding members keeps the first ones' seeds


def test_ensemble_on_a_real_scheduler_and_worker(dask_cluster_processes, geometries_dir,
                                                 tmp_path, capsys):
    address, worker = dask_cluster_processes
    out = tmp_path / "ens"
    status = main(["ensemble", str(geometries_dir / ROOM), "--members", "3", "--scheduler",
                   address, "--out", str(out), "-q", "--seed", "3"])
    assert status == 0, capsys.readouterr().err
    df = pd.read_csv(out / "ensemble.csv", dtype={"member": str})
    assert list(df["member"]) == ["000-0000", "000-0001", "000-0002"]
    assert list(df["seed"]) == member_seeds(3, 3)
    assert set(df["status"]) == {"finished"}
    assert set(df["worker"]) == {worker}  # the worker process did the work
    assert (df["n_evacuated"] == 88).all()
    stats = json.loads((out / "ensemble.json").read_text())["points"][0]
    for key in ("t_evac_50", "t_evac_90", "t_evac_100"):
        v = df[key].to_numpy()
        p5, p50, p95 = np.percentile(v, [5, 50, 95])
        got = stats[key]
        assert got["n"] == 3
        assert got["p5"] == pytest.approx(p5) and got["p50"] == pytest.approx(p50)
        assert got["p95"] == pytest.approx(p95) and got["mean"] == pytest.approx(v.mean())
        assert got["std"] == pytest.approx(v.std(ddof=1))
    assert (out / "evacuation_bands.png").stat().st_size > 10_000
    for m in df["member"]:
        s = json.loads((out / "members" / m / "summary.json").read_text())
        assert s["status"] == "finished"


def test_default_local_cluster(geometries_dir, tmp_path):
    df = ensemble(geometries_dir / ROOM, "sfm", 2, tmp_path / "ens", workers=2, quiet=True,
                  t_end=20.0)
    assert len(df) == 2 and set(df["status"]) == {"stopped at t_end"}
    assert all(w.startswith("tcp://127.0.0.1:") for w in df["worker"])


def test_failed_member_is_recorded_and_others_finish(client, geometries_dir, tmp_path):
    df = ensemble(geometries_dir / ROOM, "sfm", 2, tmp_path / "ens", client=client,
                  sweep={"dt": [0.01, -1.0]}, quiet=True, t_end=15.0)
    good, bad = df[df["dt"] == 0.01], df[df["dt"] == -1.0]
    assert set(good["status"]) == {"stopped at t_end"} and len(good) == 2
    assert set(bad["status"]) == {"failed"} and len(bad) == 2
    assert all("dt" in e for e in bad["error"])
    summary = json.loads((tmp_path / "ens" / "ensemble.json").read_text())
    assert [p["failed"] for p in summary["points"]] == [0, 2]


def test_rerun_skips_finished_members(client, geometries_dir, tmp_path, capsys):
    out = tmp_path / "ens"
    first = ensemble(geometries_dir / ROOM, "sfm", 2, out, client=client, t_end=10.0)
    capsys.readouterr()
    stamp = {m: (out / "members" / m / "summary.json").stat().st_mtime_ns
             for m in first["member"]}
    again = ensemble(geometries_dir / ROOM, "sfm", 3, out, client=client, t_end=10.0)
    assert "2 of 3 members already finished (skipped)" in capsys.readouterr().err
    for m, t in stamp.items():
        assert (out / "members" / m / "summary.json").stat().st_mtime_ns == t
    pd.testing.assert_frame_equal(again.iloc[:2][["t_evac_50", "n_evacuated", "worker"]],
                                  first[["t_evac_50", "n_evacuated", "worker"]])
    assert again.iloc[2]["status"] == "stopped at t_end"
    # a member folder made with other settings is an error, not reused
    with pytest.raises(EnsembleError, match="t_end"):
        ensemble(geometries_dir / ROOM, "sfm", 2, out, client=client, t_end=11.0)


def test_seeds_change_the_start_and_the_result(client, geometries_dir, tmp_path):
    import pedpy
    from pathlib import Path

    df = ensemble(geometries_dir / ROOM, "sfm", 2, tmp_path / "a", client=client, seed=5)
    again = ensemble(geometries_dir / ROOM, "sfm", 1, tmp_path / "b", client=client, seed=5)
    assert df.iloc[0]["seed"] == again.iloc[0]["seed"]
    assert df.iloc[0]["t_evac_100"] == again.iloc[0]["t_evac_100"]  # same seed, same run
    assert df.iloc[0]["t_evac_100"] != df.iloc[1]["t_evac_100"]

    def start(out: Path) -> np.ndarray:
        t = pedpy.load_trajectory_from_txt(trajectory_file=out / "trajectories.txt").data
        return t[t["frame"] == 0].sort_values("id")[["x", "y"]].to_numpy()

    a0, a1 = (start(tmp_path / "a" / "members" / m) for m in df["member"])
    b0 = start(tmp_path / "b" / "members" / again.iloc[0]["member"])
    assert np.array_equal(a0, b0) and not np.allclose(a0, a1)


def test_bad_options_are_one_line(geometries_dir, tmp_path, capsys):
    room = str(geometries_dir / ROOM)
    for args, message in ((["--members", "0"], "members must be a positive integer"),
                          (["--sweep", "dt"], "--sweep expects NAME=V1,V2"),
                          (["--model", "rdue", "--members", "3"], "no random input"),
                          (["--param", "dt=0.01", "--sweep", "dt=0.01,0.02"],
                           "both set and swept"),
                          (["--max-cells", "100"], "more than the limit of 100")):
        assert main(["ensemble", room, "--out", str(tmp_path / "x"), "-q", *args]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], (args, err)


# ------------------------------------------------------------------ faults (issue 36)
FINISHED = ("finished", "stopped at t_end")
#: the columns of ensemble.csv that come from a member's summary.json
FROM_SUMMARY = ("status", "n_initial", "n_evacuated", "t_evac_50", "t_evac_90", "t_evac_100",
                "wall_time_s")


@pytest.fixture(scope="module")
def room_b(tmp_path_factory):
    """Room B of issue 36: 10 x 5 m, a 1 m door, 20 people (a member takes seconds)."""
    path = tmp_path_factory.mktemp("room") / "room_b.json"
    path.write_text(json.dumps({
        "format": "pedmesh-room", "version": 1, "name": "B", "units": "m",
        "outline": [[0, 0], [10, 0], [10, 5], [0, 5]],
        "exits": [{"name": "door", "polyline": [[10, 2], [10, 3]]}],
        "start_areas": [{"name": "crowd", "polygon": [[1, 1], [6, 1], [6, 4], [1, 4]],
                         "count": 20}]}))
    return path


def _summary(folder):
    try:
        return json.loads((folder / "summary.json").read_text())
    except (OSError, ValueError):
        return None


def _assert_csv_agrees_with_summaries(out, *, statuses=FINISHED):
    """Every row of ensemble.csv says what its member's summary.json says."""
    from pedmesh.run.output import run_status

    df = pd.read_csv(out / "ensemble.csv", dtype={"member": str}, keep_default_na=False)
    for row in df.to_dict("records"):
        folder = out / "members" / row["member"]
        s = _summary(folder)
        assert s is not None, f"member {row['member']}: no summary.json"
        assert run_status(folder, s) in statuses, (row["member"], s.get("status"))
        for key in FROM_SUMMARY:
            assert row[key] == pytest.approx(s[key]) if isinstance(s[key], float) \
                else row[key] == s[key], (row["member"], key, row[key], s[key])
    return df


def _tasks(room, out, members, t_end=30.0, overrides=None):
    """The tasks ensemble() sends to its workers, by hand (as benchmarks/ensemble.py does)."""
    from pedmesh.ensembles.plan import plan_members
    from pedmesh.io import load_room
    from pedmesh.mesh.triangulate import FEATURE_AREA, MAX_AREA, MIN_ANGLE
    from pedmesh.presets import resolve_preset

    preset = resolve_preset(None, load_room(room))
    mesh_options = {"max_area": MAX_AREA, "min_angle": MIN_ANGLE,
                    "feature_area": FEATURE_AREA, "exit_size": None}
    plan = plan_members(str(room), "sfm", members, out, overrides=dict(overrides or {}),
                        sweep={}, seed=0, t_end=t_end, mesh_options=mesh_options,
                        preset=preset, seeded=True)
    return [{"member": m.member, "point": m.point, "seed": m.seed, "values": {},
             "geometry": str(room.resolve()), "model": "sfm", "overrides": m.overrides,
             "t_end": t_end, "out_dir": str(m.out_dir.resolve()), "mesh_options": mesh_options,
             "preset": preset, "max_cells": None, "model_options": {"seed": m.seed}}
            for m in plan]


def test_killed_worker_loses_no_finished_member(room_b, tmp_path):
    """Issue 36, item 1: SIGKILL a worker that finished a member and now runs another.
    Its finished member is neither cleared nor recomputed, the killed member is run again,
    and ensemble.csv agrees with every member's summary."""
    import os
    import re
    import signal
    from pathlib import Path

    import pedmesh

    out = tmp_path / "ens"
    members = out / "members"
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(Path(pedmesh.__file__).parents[1]),
                                         env.get("PYTHONPATH", "")])
    proc = subprocess.Popen(
        [sys.executable, "-m", "pedmesh", "ensemble", str(room_b), "--members", "3",
         "--workers", "2", "--param", "dt=0.0005", "--t-end", "60", "--out", str(out), "-q"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    victim = before = None
    try:
        deadline = time.time() + 240
        while victim is None and proc.poll() is None and time.time() < deadline:
            seen = {d.name: s for d in (members.iterdir() if members.is_dir() else ())
                    if (s := _summary(d)) is not None}
            running = {s.get("pid") for s in seen.values() if s.get("status") == "running"}
            for name, s in seen.items():
                if re.fullmatch(r"\d{3}-\d{4}", name) and s.get("status") in FINISHED \
                        and s.get("pid") in running:
                    victim = name
                    before = (members / name / "summary.json").read_bytes()
                    os.kill(s["pid"], signal.SIGKILL)  # the worker, mid-way through another
                    break
            time.sleep(0.02)
        stdout, stderr = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert victim is not None, "never saw a worker start a member after finishing one"
    assert proc.returncode == 0, stderr
    assert "3 of 3 members finished, 0 failed" in stdout
    df = _assert_csv_agrees_with_summaries(out, statuses=("finished",))
    assert list(df["member"]) == ["000-0000", "000-0001", "000-0002"]
    assert (members / victim / "summary.json").read_bytes() == before  # never recomputed
    assert sorted(p.name for p in members.iterdir()) == list(df["member"])  # no temp folders


def test_recompute_of_a_finished_member_returns_its_summary(room_b, tmp_path):
    """What Dask does when a worker holding a finished member's result dies: it runs the
    task again. The member's folder is then left alone and its summary returned."""
    from pedmesh.ensembles import run_member

    task = _tasks(room_b, tmp_path / "ens", 1)[0]
    first = run_member(task)
    assert first["status"] == "finished", first
    folder = tmp_path / "ens" / "members" / "000-0000"
    stamps = {p.name: p.stat().st_mtime_ns for p in folder.iterdir()}
    summary = _summary(folder)
    again = run_member(task)
    assert {p.name: p.stat().st_mtime_ns for p in folder.iterdir()} == stamps
    for key in FROM_SUMMARY:
        assert again[key] == summary[key] == first[key], key


def test_member_cut_off_midway_never_takes_its_place(room_b, tmp_path, client, monkeypatch):
    """A member that stops after writing part of its output (a fault injected into its
    writer) leaves no cut-off run under its name; the next ensemble runs it again."""
    from pedmesh.ensembles import run_member
    from pedmesh.run.output import RunWriter

    out = tmp_path / "ens"
    task = _tasks(room_b, out, 1)[0]
    real, calls = RunWriter.sample, []

    def dies(self, t, evacuated):
        real(self, t, evacuated)
        calls.append(t)
        if len(calls) == 20:
            raise KeyboardInterrupt  # as a signal would, after 2 s of output
    monkeypatch.setattr(RunWriter, "sample", dies)
    row = run_member(task)
    monkeypatch.undo()
    assert row["status"] != "finished" and len(calls) == 20
    assert not (out / "members" / "000-0000").exists()
    assert list((out / "members").iterdir()) == []  # nor its temporary folder

    df = ensemble(room_b, "sfm", 1, out, client=client, quiet=True, t_end=30.0)
    assert list(df["status"]) == ["finished"]
    _assert_csv_agrees_with_summaries(out)
    assert [p.name for p in (out / "members").iterdir()] == ["000-0000"]


def test_failed_member_is_in_place_with_its_error_and_rerun(room_b, tmp_path, client,
                                                            monkeypatch):
    """A member whose run fails midway (here: its writer fails) is recorded as failed, its
    folder says so with the error, ensemble.csv agrees; the next ensemble runs it again."""
    from pedmesh.ensembles import run_member
    from pedmesh.run.output import RunWriter

    out = tmp_path / "ens"
    task = _tasks(room_b, out, 1)[0]
    real, calls = RunWriter.sample, []

    def fails(self, t, evacuated):
        real(self, t, evacuated)
        calls.append(t)
        if len(calls) == 20:
            raise OSError(28, "No space left on device", "evacuation.csv")
    monkeypatch.setattr(RunWriter, "sample", fails)
    row = run_member(task)
    monkeypatch.undo()
    folder = out / "members" / "000-0000"
    s = _summary(folder)
    assert row["status"] == s["status"] == "failed"
    assert "No space left on device" in s["error"] and row["error"] == s["error"]
    assert [p.name for p in (out / "members").iterdir()] == ["000-0000"]

    df = ensemble(room_b, "sfm", 1, out, client=client, quiet=True, t_end=30.0)
    assert list(df["status"]) == ["finished"]
    _assert_csv_agrees_with_summaries(out)


def test_interrupted_ensemble_takes_statuses_from_the_summaries(room_b, tmp_path, client,
                                                                monkeypatch):
    """Issue 36, item 12: Ctrl-C while a member has finished on its worker but is not yet
    collected; ensemble.csv still says `finished` for it, as its summary does."""
    from pedmesh.ensembles import running

    out = tmp_path / "ens"
    real = running.write_csv  # (ensemble.csv as the members are collected)
    state = {"raised": False}

    def interrupted(path, frame):
        real(path, frame)
        if not state["raised"] and frame["status"].isin(FINISHED).sum() == 1:
            state["raised"] = True
            deadline = time.time() + 120
            while time.time() < deadline and not all(
                    (_summary(out / "members" / m) or {}).get("status") in FINISHED
                    for m in ("000-0000", "000-0001")):
                time.sleep(0.05)
            raise KeyboardInterrupt
    monkeypatch.setattr(running, "write_csv", interrupted)
    with pytest.raises(KeyboardInterrupt):
        ensemble(room_b, "sfm", 2, out, client=client, quiet=True, t_end=30.0)
    assert state["raised"]
    df = _assert_csv_agrees_with_summaries(out)
    assert list(df["status"]) == ["finished", "finished"]


def test_out_must_be_empty_or_a_pedmesh_ensemble(room_b, tmp_path, capsys):
    """Issue 36, item 5: --out has the ownership check of `pedmesh run --out`."""
    room = str(room_b)
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("my notes\n")
    theirs = tmp_path / "theirs"
    theirs.mkdir()
    (theirs / "ensemble.csv").write_text("a,b\n1,2\n")
    a_run = tmp_path / "a-run"
    assert main(["run", room, "--out", str(a_run), "-q", "--t-end", "1"]) == 0
    capsys.readouterr()
    for folder in (mine, theirs, a_run):
        listing = sorted(p.name for p in folder.iterdir())
        assert main(["ensemble", room, "--members", "1", "--out", str(folder), "-q"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and str(folder) in err[0] and "not a pedmesh ensemble" in err[0], err
        assert sorted(p.name for p in folder.iterdir()) == listing  # nothing written
    assert (theirs / "ensemble.csv").read_text() == "a,b\n1,2\n"


def test_out_of_an_ensemble_keeps_other_files_and_refuses_a_second_writer(room_b, tmp_path,
                                                                         client, capsys):
    import fcntl

    out = tmp_path / "ens"
    ensemble(room_b, "sfm", 1, out, client=client, quiet=True, t_end=5.0)
    (out / "notes.txt").write_text("my notes\n")
    df = ensemble(room_b, "sfm", 2, out, client=client, quiet=True, t_end=5.0)
    assert len(df) == 2 and (out / "notes.txt").read_text() == "my notes\n"
    with open(out / ".lock", "a+") as lock:  # another ensemble is writing into it
        fcntl.flock(lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        assert main(["ensemble", str(room_b), "--members", "2", "--out", str(out), "-q",
                     "--t-end", "5"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(out) in err[0] and "another" in err[0], err


def test_bad_scheduler_address_is_one_line(room_b, tmp_path, capsys):
    """Issue 36, item 10: not an internal error."""
    for address in ("notanaddress", "tcp://host", "foo://host:1", "tcp://host:port"):
        assert main(["ensemble", str(room_b), "--members", "1", "--scheduler", address,
                     "--out", str(tmp_path / "x"), "-q"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and address in err[0] and "internal" not in err[0], err
        assert not (tmp_path / "x").exists()


def test_unknown_parameter_is_refused_before_any_cluster(room_b, tmp_path, capsys,
                                                         monkeypatch):
    """Issue 36, item 10: sweep and --param names are checked against the model's declared
    parameters before a cluster starts (here, starting one fails the test)."""
    import distributed

    def no_cluster(*args, **kwargs):
        raise AssertionError("a cluster was started")
    monkeypatch.setattr(distributed, "LocalCluster", no_cluster)
    monkeypatch.setattr(distributed, "Client", no_cluster)
    for args, name in ((["--sweep", "foo=1,2"], "foo"), (["--param", "bar=1"], "bar"),
                       (["--model", "eos", "--sweep", "dt=0.01,0.02"], "dt")):
        assert main(["ensemble", str(room_b), "--members", "1", "--out",
                     str(tmp_path / "x"), "-q", *args]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"unknown parameter '{name}'" in err[0], err
        assert not (tmp_path / "x").exists()


def test_rerun_repairs_what_a_killed_ensemble_left(room_b, tmp_path, client, capsys):
    """A member folder with a cut-off run (summary `running`, its process gone: what issue
    36's worker kill left behind) is run again, a killed attempt's temporary folder is
    removed, and a file of the user's in a folder that must be cleared stops the ensemble
    in one line, before that folder is touched."""
    out = tmp_path / "ens"
    ensemble(room_b, "sfm", 2, out, client=client, quiet=True, t_end=30.0)
    cut = out / "members" / "000-0001"
    s = _summary(cut)
    s.update(status="running", pid=2 ** 22 + 12345, n_evacuated=3)  # no such process
    (cut / "summary.json").write_text(json.dumps(s))
    scratch = out / "members" / "000-0000.tmp-999-1"
    scratch.mkdir()
    (scratch / ".lock").touch()
    (scratch / "summary.json").write_text("{}")
    finished = (out / "members" / "000-0000" / "summary.json").read_bytes()

    (cut / "my-notes.txt").write_text("mine\n")
    assert main(["ensemble", str(room_b), "--members", "2", "--out", str(out), "-q",
                 "--t-end", "30"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "my-notes.txt" in err[0], err
    assert (cut / "my-notes.txt").exists() and _summary(cut)["status"] == "running"

    (cut / "my-notes.txt").unlink()
    df = ensemble(room_b, "sfm", 2, out, client=client, quiet=True, t_end=30.0)
    assert list(df["status"]) == ["finished", "finished"]
    _assert_csv_agrees_with_summaries(out)
    assert (out / "members" / "000-0000" / "summary.json").read_bytes() == finished
    assert sorted(p.name for p in (out / "members").iterdir()) == ["000-0000", "000-0001"]
