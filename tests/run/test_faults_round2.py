"""The second fault sweep (issue 48): each defect it found, as a test that failed before
its fix."""

from __future__ import annotations

import json
import signal
from pathlib import Path

import numpy as np
import pytest

import pedmesh
from pedmesh.cli import main
from pedmesh.run import RunResult
from test_faults import _one_line_error  # (the first sweep's: one line, not internal)

#: exit names a user may well write: quotes, a comma, a newline, non-ASCII
NAMES = ('Door "A"', "Door A, north", 'Tür "Ä",\nnord')


def _room(tmp_path: Path, names=NAMES[:2], n: int = 20) -> Path:
    room = {
        "format": "pedmesh-room", "version": 1, "name": "r", "units": "m",
        "outline": [[0, 0], [10, 0], [10, 6], [0, 6]],
        "exits": [{"name": names[0], "polyline": [[10, 2], [10, 4]]},
                  {"name": names[1], "polyline": [[0, 2], [0, 4]]}],
        "start_areas": [{"name": "crowd", "polygon": [[3, 1], [7, 1], [7, 5], [3, 5]],
                         "count": n}],
    }
    p = tmp_path / "room.json"
    p.write_text(json.dumps(room), encoding="utf-8")
    return p


# ---------------------------------------------------------------- names are data
@pytest.mark.parametrize("names", [NAMES[:2], NAMES[1:]])
@pytest.mark.parametrize("model", ["sfm", "eos"])
def test_exit_names_round_trip_into_the_safety_record_and_report(tmp_path, names, model):
    room = _room(tmp_path, names)
    out = tmp_path / "run"
    assert main(["run", str(room), "--model", model, "--out", str(out), "-q",
                 "--t-end", "40"]) == 0
    s = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    safety = s["safety"]
    assert "error" not in safety, safety
    assert set(safety["exits"]) == set(names)
    # (a continuum's passages are its sampled outflow integrated: within a person of 20)
    assert sum(e["people"] for e in safety["exits"].values()) == pytest.approx(
        20, abs=0.01 if model == "sfm" else 1.0)
    assert (out / "safety.vtu").is_file()
    res = RunResult.load(out)
    assert res.outflow[2] == list(names)
    html = tmp_path / "r.html"
    assert main(["report", str(out), "-o", str(html)]) == 0
    text = html.read_text(encoding="utf-8")
    assert "&quot;&quot;" not in text and '""' not in text.replace('=""', "")


def test_exit_names_round_trip_in_memory(tmp_path):
    res = pedmesh.simulate(_room(tmp_path, NAMES[1:]), model="sfm", t_end=40.0)
    safety = res.summary["safety"]
    assert "error" not in safety, safety
    assert set(safety["exits"]) == set(NAMES[1:])
    assert np.isfinite(res.exit_times).all() and len(res.exit_times) == 20


# ---------------------------------------------------------------- readers name the file
@pytest.fixture(scope="module")
def small_run(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("small")
    out = tmp / "run"
    assert main(["run", str(_room(tmp)), "--out", str(out), "-q", "--t-end", "40"]) == 0
    return out


def _damaged(small_run: Path, tmp_path: Path, how: str) -> tuple[Path, Path]:
    import shutil

    d = tmp_path / how
    shutil.copytree(small_run, d)
    if how == "evacuation garbage":
        with open(d / "evacuation.csv", "a") as f:
            f.write("not,a number\n")
        return d, d / "evacuation.csv"
    f = sorted((d / "density").glob("*.vtu"))[0 if how.startswith("first") else 2]
    if how.endswith("truncated"):
        f.write_bytes(f.read_bytes()[:300])
    elif how.endswith("garbage"):
        f.write_text("not a frame")
    else:
        f.unlink()
    return d, f


@pytest.mark.parametrize("how", ["first truncated", "frame truncated", "frame garbage",
                                 "frame deleted", "evacuation garbage"])
@pytest.mark.parametrize("command", ["report", "animate"])
def test_readers_name_the_broken_file(small_run, tmp_path, capfd, how, command):
    # (capfd: VTK's own error printing, on the C level, must not reach stderr either)
    d, broken = _damaged(small_run, tmp_path, how)
    capfd.readouterr()
    out = tmp_path / ("r.html" if command == "report" else "a.gif")
    args = [command, str(d), "-o", str(out)] + (["--max-frames", "40"]
                                                  if command == "animate" else [])
    assert main(args) == 2
    line = _one_line_error(capfd)
    assert str(broken) in line
    assert not out.exists()


# ---------------------------------------------------------------- a rerun's clean-up
def test_rerun_keeps_the_users_files_in_the_run_subfolders(tmp_path):
    room, out = _room(tmp_path), tmp_path / "run"
    assert main(["run", str(room), "--out", str(out), "-q", "--t-end", "8"]) == 0
    old = sorted(p.name for p in (out / "density").glob("density_*.vtu"))
    assert len(old) >= 5
    (out / "density" / "my_notes.txt").write_text("mine")
    (out / "pedestrians" / "pedestrians_notes.vtp").write_text("mine too")
    (out / "my_notes.txt").write_text("top level")
    assert main(["run", str(room), "--out", str(out), "-q", "--t-end", "2"]) == 0
    assert (out / "density" / "my_notes.txt").read_text() == "mine"
    assert (out / "pedestrians" / "pedestrians_notes.vtp").read_text() == "mine too"
    assert (out / "my_notes.txt").read_text() == "top level"
    new = sorted(p.name for p in (out / "density").glob("density_*.vtu"))
    assert 0 < len(new) < len(old)  # the earlier run's later frames are gone
    from pedmesh.io.vtk import read_pvd_index

    assert sorted(p.name for _, p in read_pvd_index(out / "density.pvd")) == new
    # without the user's files the folders are removed and written anew as before
    (out / "density" / "my_notes.txt").unlink()
    assert main(["run", str(room), "--out", str(out), "-q", "--t-end", "1"]) == 0
    assert sorted(p.name for p in (out / "density").iterdir()) == sorted(
        p.name for _, p in read_pvd_index(out / "density.pvd"))


# ---------------------------------------------------------------- Ctrl-C in the API
@pytest.mark.parametrize("on_disk", [False, True])
def test_ctrl_c_in_simulate_carries_the_partial_result(tmp_path, on_disk, monkeypatch):
    import _thread

    from pedmesh.models.sfm import Simulation
    from pedmesh.run import RunInterrupted

    room = tmp_path / "slow.json"  # 150 people, one 1 m door: about 50 s to empty
    room.write_text(json.dumps({
        "format": "pedmesh-room", "version": 1, "name": "slow", "units": "m",
        "outline": [[0, 0], [20, 0], [20, 10], [0, 10]],
        "exits": [{"name": "d", "polyline": [[20, 4.5], [20, 5.5]]}],
        "start_areas": [{"name": "crowd", "polygon": [[1, 1], [9, 1], [9, 9], [1, 9]],
                         "count": 150}]}))
    pedmesh.simulate(room, model="sfm", t_end=0.5)  # (compiled kernels loaded)
    # Ctrl-C in the middle of the stepping, 2 s of simulated time in (a timer of wall time
    # fired during the set-up on a loaded machine, before anything was recorded)
    step = Simulation.step

    def step_then_ctrl_c(self):
        k = step(self)
        if self.t >= 2.0 and not getattr(self, "_ctrl_c_sent", False):
            self._ctrl_c_sent = True
            _thread.interrupt_main()
        return k

    monkeypatch.setattr(Simulation, "step", step_then_ctrl_c)
    # Python's own Ctrl-C handler, whatever the test runner was started with (under nohup,
    # SIGINT is ignored and interrupt_main would do nothing)
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt) as info:
            pedmesh.simulate(room, model="sfm", t_end=200.0, params={"dt": 1e-3},
                             out_dir=tmp_path / "run" if on_disk else None)
    finally:
        signal.signal(signal.SIGINT, before)
    exc = info.value
    assert isinstance(exc, RunInterrupted) and isinstance(exc, pedmesh.PedmeshError)
    res = exc.result
    assert res is not None and res.summary["status"] == "interrupted"
    t, n = res.evacuation
    assert len(t) > 0 and t[-1] == pytest.approx(exc.t, abs=1.0)
    assert 2.0 <= exc.t < 3.0


# ---------------------------------------------------------------- the API's arguments
@pytest.mark.parametrize("kwargs, words", [
    (dict(mesh="mesh.vtu"), ["mesh must be", "mesh_options"]),
    (dict(params=["A", 1]), ["params must be a mapping"]),
    (dict(params={1: 2.0}), ["parameter names are text"]),
    (dict(t_end="10"), ["t_end", "str"]),
    (dict(t_end=True), ["t_end", "bool"]),
    (dict(out_dir=123), ["out_dir", "int"]),
    (dict(mesh_options={"colour": 1}), ["mesh_options", "'colour'", "max_area"]),
    (dict(mesh_options=[1]), ["mesh_options must be a mapping"]),
    (dict(quiet="no"), ["quiet"]),
])
def test_simulate_checks_its_arguments_at_the_door(tmp_path, kwargs, words):
    with pytest.raises(pedmesh.PedmeshError) as info:
        pedmesh.simulate(_room(tmp_path), **{"t_end": 1.0, **kwargs})
    assert all(w in str(info.value) for w in words), str(info.value)
    assert "\n" not in str(info.value)
    if "mesh" in kwargs or "params" in kwargs or "mesh_options" in kwargs:
        with pytest.raises(pedmesh.PedmeshError):
            pedmesh.build(_room(tmp_path), **kwargs)


def test_simulate_names_a_missing_room_file(tmp_path):
    with pytest.raises(pedmesh.PedmeshError, match="no such room file"):
        pedmesh.simulate("this is not a room")
    with pytest.raises(pedmesh.PedmeshError, match="no such room file"):
        pedmesh.simulate(tmp_path / "missing.json")


# ---------------------------------------------------------------- absurd step counts
def test_absurd_step_counts_are_refused_before_the_run(tmp_path, capsys):
    room, out = _room(tmp_path), tmp_path / "run"
    assert main(["run", str(room), "--out", str(out), "--t-end", "1e12",
                 "--param", "dt=1e-4"]) == 2
    line = _one_line_error(capsys)
    assert "1e+16 time steps" in line and "--max-steps" in line
    assert not out.exists()
    with pytest.raises(pedmesh.PedmeshError, match="max_steps=N"):
        pedmesh.simulate(room, t_end=1e12, params={"dt": 1e-4})
    # allowed when asked for
    res = pedmesh.simulate(room, t_end=30.0, params={"dt": 1e-3}, max_steps=30_000)
    assert res.summary["status"] == "finished"
    with pytest.raises(pedmesh.PedmeshError, match="30,000 time steps|3e\\+04 time steps"):
        pedmesh.simulate(room, t_end=30.0, params={"dt": 1e-3}, max_steps=29_999)


# ---------------------------------------------------------------- why no safety measures
@pytest.mark.parametrize("case", ["error", "running", "old"])
def test_report_says_why_the_safety_measures_are_missing(small_run, tmp_path, case):
    import fcntl
    import shutil

    d = tmp_path / case
    shutil.copytree(small_run, d)
    s = json.loads((d / "summary.json").read_text())
    if case == "error":
        s["safety"] = {"error": "ValueError: boom"}
        want = "could not be computed: ValueError: boom"
    else:
        s.pop("safety")
        want = "still running" if case == "running" else "made before pedmesh recorded"
        if case == "running":
            s["status"] = "running"
    (d / "summary.json").write_text(json.dumps(s))
    lock = open(d / ".lock", "a+")
    try:
        if case == "running":  # (a live run holds its lock)
            fcntl.flock(lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        out = tmp_path / "r.html"
        assert main(["report", str(d), "-o", str(out)]) == 0
    finally:
        lock.close()
    text = out.read_text(encoding="utf-8")
    assert want in text
    assert "made before pedmesh" not in text or case == "old"


# ---------------------------------------------------------------- outputs of report/animate
@pytest.mark.parametrize("command", ["report", "animate"])
def test_an_unwritable_output_is_refused_before_the_work(small_run, tmp_path, capsys,
                                                         monkeypatch, command):
    import pedmesh.animate
    import pedmesh.report

    def never(*a, **k):
        raise AssertionError("the work was done before the output was checked")

    monkeypatch.setattr(pedmesh.report, "build_report", never)
    monkeypatch.setattr(pedmesh.animate, "_Frames", never)
    out = Path("/proc/pedmesh-not-writable") / ("r.html" if command == "report" else "a.gif")
    assert main([command, str(small_run), "-o", str(out)]) == 2
    line = _one_line_error(capsys)
    assert f"cannot write {out}" in line


def test_a_full_disk_in_report_names_the_file(small_run, tmp_path, capsys, monkeypatch):
    import errno
    import os

    real = Path.write_text

    def full(self, *a, **k):
        if ".part" in self.name and self.name.endswith(".html"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))  # (no file name)
        return real(self, *a, **k)

    monkeypatch.setattr(Path, "write_text", full)
    out = tmp_path / "r.html"
    assert main(["report", str(small_run), "-o", str(out)]) == 2
    line = _one_line_error(capsys)
    assert f"cannot write {out}: {os.strerror(errno.ENOSPC)}" in line
    assert not out.exists() and not [p for p in tmp_path.iterdir() if ".part" in p.name]


# ---------------------------------------------------------------- a refused scheduler port
def test_a_refused_scheduler_port_says_so_at_once(tmp_path, capsys):
    import time

    pytest.importorskip("distributed")
    t0 = time.perf_counter()
    assert main(["ensemble", str(_room(tmp_path)), "--members", "1", "--scheduler",
                 "tcp://127.0.0.1:1", "--out", str(tmp_path / "e"), "-q"]) == 2
    line = _one_line_error(capsys)
    assert "tcp://127.0.0.1:1" in line and "refused" in line
    assert time.perf_counter() - t0 < 10.0  # (was Dask's 20 s timeout, 31 s in all)
    assert not (tmp_path / "e").exists()


@pytest.mark.parametrize("command", ["report", "animate"])
def test_a_users_part_file_beside_the_output_is_kept(small_run, tmp_path, command):
    out = tmp_path / ("mine.html" if command == "report" else "mine.gif")
    theirs = [out.with_name(out.name + ".part"), out.with_name(out.stem + ".part" + out.suffix)]
    for p in theirs:
        p.write_text("the user's draft")
    args = [command, str(small_run), "-o", str(out)] + (["--max-frames", "3"]
                                                       if command == "animate" else [])
    assert main(args) == 0 and out.stat().st_size > 1000
    assert all(p.read_text() == "the user's draft" for p in theirs)
    assert sorted(p.name for p in tmp_path.iterdir() if ".part" in p.name) == sorted(
        p.name for p in theirs)


def test_level_names_with_spaces_and_newlines_keep_trajectories_whole(tmp_path):
    import copy
    import sys
    from urllib.parse import unquote

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from building_data import TWO

    b = copy.deepcopy(TWO)
    name = 'G Tür "Ä",\nzwei 50%' + "x" * 90  # (and longer than 64 characters)
    b["levels"][0]["name"] = name
    for end in ("bottom", "top"):
        if b["stairs"][0][end]["level"] == "ground":
            b["stairs"][0][end]["level"] = name
    room = tmp_path / "b.json"
    room.write_text(json.dumps({"format": "pedmesh-room", "version": 1, "units": "m", **b}))
    out = tmp_path / "run"
    assert main(["run", str(room), "--out", str(out), "-q", "--t-end", "20"]) == 0
    rows = [ln.split() for ln in (out / "trajectories.txt").read_text().splitlines()
            if not ln.startswith("#")]
    assert rows and all(len(r) == 6 for r in rows)
    assert {unquote(r[5]) for r in rows} <= {name, "first", "stair"}
    assert name in {unquote(r[5]) for r in rows}
    mem = pedmesh.simulate(room, t_end=20.0)
    assert name in set(mem.trajectories["place"])


# ---------------------------------------------------------------- the sweep's re-run
def _edit_summary(d: Path, **changes) -> None:
    s = json.loads((d / "summary.json").read_text())
    for k, v in changes.items():
        if "." in k:
            a, b = k.split(".")
            s[a][b] = v
        else:
            s[k] = v
    (d / "summary.json").write_text(json.dumps(s))


@pytest.mark.parametrize("field, value", [
    ("geometry", 5), ("warnings", 5), ("safety.peak_density", [1, 2]),
    ("safety.time_above", [0, 0]), ("safety.level_of_service", "E"),
    ("safety.exits", "east"), ("settings.overrides", [1, 2]), ("safety", "broken")])
def test_report_names_a_summary_field_of_the_wrong_kind(small_run, tmp_path, capsys, field,
                                                        value):
    import shutil

    d = tmp_path / "run"
    shutil.copytree(small_run, d)
    _edit_summary(d, **{field: value})
    assert main(["report", str(d), "-o", str(tmp_path / "r.html")]) == 2
    line = _one_line_error(capsys)
    assert "summary.json" in line and field.split(".")[-1] in line


def test_a_huge_process_id_reads_as_interrupted(small_run, tmp_path):
    import shutil

    d = tmp_path / "run"
    shutil.copytree(small_run, d)
    _edit_summary(d, status="running", pid=10 ** 30)
    (d / ".lock").unlink(missing_ok=True)
    assert RunResult.load(d).status == "interrupted"
    assert main(["report", str(d), "-o", str(tmp_path / "r.html")]) == 0


def _damage(small_run: Path, tmp_path: Path, how: str) -> tuple[Path, str]:
    """A copy of the run, damaged; and a word the error must hold."""
    import shutil

    d = tmp_path / how
    shutil.copytree(small_run, d)
    frames = sorted((d / "density").glob("*.vtu"))
    if how == "quad frame":
        import meshio

        meshio.write(frames[0], meshio.Mesh(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0],
                                                      [0, 1, 0.0]]), [("quad", [[0, 1, 2, 3]])]))
        return d, frames[0].name
    if how == "frame without density":
        shutil.copy(d / "safety.vtu", frames[3])
        return d, frames[3].name
    if how == "frame of another mesh":
        other = pedmesh.Room([(0, 0), (4, 0), (4, 4), (0, 4)],
                             exits=[dict(name="e", polyline=[(4, 1), (4, 3)])])
        from pedmesh.io import write_vtu

        m = pedmesh.triangulate(other)
        write_vtu(frames[3], m, point_data={"density": np.zeros(m.n_points)})
        return d, frames[3].name
    if how == "pedestrian frame deleted":
        sorted((d / "pedestrians").glob("*.vtp"))[0].unlink()
        return d, "pedestrians_000000.vtp"
    if how == "pedestrian frames truncated":
        for f in (d / "pedestrians").glob("*.vtp"):
            f.write_bytes(f.read_bytes()[: f.stat().st_size // 2])
        return d, "pedestrians_"
    if how == "index deleted":
        (d / "density.pvd").unlink()
        return d, "density.pvd"
    if how == "exits.csv binary":
        (d / "exits.csv").write_bytes(b"\x00\xff" * 20)
        return d, "exits.csv"
    if how == "exits.csv short line":
        with open(d / "exits.csv", "a") as f:
            f.write("1,east\n")
        return d, "exits.csv"
    raise AssertionError(how)


_FRAME_DAMAGE = ["quad frame", "frame without density", "frame of another mesh",
                 "pedestrian frame deleted", "pedestrian frames truncated", "index deleted"]


@pytest.mark.parametrize("command, how", [
    *[("report", h) for h in _FRAME_DAMAGE + ["exits.csv binary", "exits.csv short line"]],
    *[("animate", h) for h in _FRAME_DAMAGE]])  # (animate does not read exits.csv)
def test_every_damage_is_named_by_report_and_animate(small_run, tmp_path, capfd, how,
                                                      command):
    d, word = _damage(small_run, tmp_path, how)
    out = tmp_path / ("r.html" if command == "report" else "a.gif")
    capfd.readouterr()
    # (--frames 4 / --max-frames 4: the damage may be in a frame the output does not show)
    args = [command, str(d), "-o", str(out)] + (["--frames", "4"] if command == "report"
                                                 else ["--max-frames", "4"])
    assert main(args) == 2
    line = _one_line_error(capfd)
    assert word in line and "cannot write" not in line


def test_a_cut_last_line_of_evacuation_csv_is_left_out(small_run, tmp_path):
    import shutil

    d = tmp_path / "run"
    shutil.copytree(small_run, d)
    text = (d / "evacuation.csv").read_text()
    whole = RunResult.load(d).evacuation
    for cut in (2, 3):
        (d / "evacuation.csv").write_text(text[:-cut])
        t, n = RunResult.load(d).evacuation
        assert len(t) == len(whole[0]) - 1 and np.array_equal(n, whole[1][:-1])


@pytest.mark.parametrize("table", ["comparison.csv", "ensemble.csv"])
def test_a_binary_table_of_a_compare_or_ensemble_folder_is_named(tmp_path, capsys, table):
    d = tmp_path / "f"
    d.mkdir()
    (d / table).write_bytes(b"\x00\xff" * 50)
    assert main(["report", str(d), "-o", str(tmp_path / "r.html")]) == 2
    assert table in _one_line_error(capsys)


@pytest.mark.parametrize("meta", [[1, 2], {"sweep": [1]}, {"points": "abc"}])
def test_a_malformed_ensemble_record_is_named(tmp_path, capsys, meta):
    d = tmp_path / "e"
    d.mkdir()
    (d / "ensemble.csv").write_text("member,point,seed,status\n000-0000,0,1,finished\n")
    (d / "ensemble.json").write_text(json.dumps(meta))
    assert main(["report", str(d), "-o", str(tmp_path / "r.html")]) == 2
    assert "ensemble.json" in _one_line_error(capsys)


@pytest.mark.parametrize("times", [",", "nan", "-1"])
def test_compare_refuses_bad_density_times(tmp_path, capsys, times):
    assert main(["compare", str(_room(tmp_path)), "--models", "sfm", "--times", times,
                 "--out", str(tmp_path / "c"), "-q"]) == 2
    assert "--times" in _one_line_error(capsys)


def test_compare_does_not_write_into_a_users_folder(tmp_path, capsys):
    d = tmp_path / "mine"
    d.mkdir()
    (d / "comparison.md").write_text("MINE")
    (d / "evacuation.png").write_text("PNG")
    assert main(["compare", str(_room(tmp_path)), "--models", "sfm", "--out", str(d),
                 "-q"]) == 2
    assert "not a pedmesh comparison folder" in _one_line_error(capsys)
    assert (d / "comparison.md").read_text() == "MINE"


def test_density_at_names_a_broken_frame(small_run, tmp_path, capfd):
    import shutil

    d = tmp_path / "run"
    shutil.copytree(small_run, d)
    res = RunResult.load(d)
    f = res.density_frames[2][1]
    f.write_text("garbage")
    mesh = pedmesh.triangulate(pedmesh.load_room(_room(tmp_path)))
    capfd.readouterr()
    with pytest.raises(pedmesh.PedmeshError, match=f.name + ".*cannot be read"):
        res.density_at(res.density_frames[2][0], mesh)
    assert capfd.readouterr().err == ""  # (VTK's own printing silenced)


def test_more_api_arguments_are_checked(tmp_path):
    import pedmesh.animate

    room = _room(tmp_path)
    for kw in (dict(out_dir="/proc/pedmesh-not-a-folder"), dict(out_dir="a\x00b"),
               dict(mesh_options={"size": "x"}), dict(mesh_options={"max_area": "x"})):
        with pytest.raises(pedmesh.PedmeshError):
            pedmesh.simulate(room, t_end=1.0, **kw)
    with pytest.raises(pedmesh.PedmeshError, match="fps"):
        pedmesh.animate.animate_run(tmp_path, tmp_path / "a.gif", fps="fast")
    with pytest.raises(pedmesh.PedmeshError, match="sweep"):
        pedmesh.ensemble(room, "sfm", 1, tmp_path / "e", sweep="U_f", workers=1)
