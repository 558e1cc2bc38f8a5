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
        while not sched_file.exists() and time.time() < deadline:
            time.sleep(0.1)
        assert sched_file.exists(), "the dask scheduler did not start"
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "dask", "worker", "--scheduler-file", str(sched_file),
             "--host", "127.0.0.1", "--nthreads", "1", "--nworkers", "1", "--no-dashboard"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        address = json.loads(sched_file.read_text())["address"]
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
