"""Faults and misuse around a run folder (issue 36): a rerun removes only pedmesh's own
files, a full disk ends as `failed` naming the file, a broken summary.json does not block
a folder, exit names with commas or newlines survive the CSV files, a room is not run on
another room's mesh, a refused folder keeps no .lock, a parameter given twice is refused.

The full disk is a fault injected into the writer: after it, every write of new data
fails with ENOSPC until space is freed (pedmesh's .part files removed or the reserve in
.lock given back), as on a real full disk. One test hits a real write limit
(RLIMIT_FSIZE) in a child process.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pedmesh
from pedmesh.cli import main
from pedmesh.errors import ParameterError, PedmeshError
from pedmesh.mesh import TriMesh, triangulate
from pedmesh.run import RunResult, RunWriter, run_model
from pedmesh.run import output as output_module
from pedmesh.run.output import run_status

ENOSPC_TEXT = os.strerror(errno.ENOSPC)

#: room B of the issue: 10 x 5 m, 20 people, 1 m doors with a comma, a newline and quotes
#: in their names
DOOR_1 = "Door 1, north"
DOOR_2 = 'Door 2\nsouth "back"'
ROOM_B = {
    "format": "pedmesh-room", "version": 1, "name": "B", "units": "m",
    "outline": [[0, 0], [10, 0], [10, 5], [0, 5]],
    "exits": [{"name": DOOR_1, "polyline": [[4.5, 5], [5.5, 5]]},
              {"name": DOOR_2, "polyline": [[4.5, 0], [5.5, 0]]}],
    "start_areas": [{"name": "crowd", "polygon": [[1, 1], [9, 1], [9, 4], [1, 4]],
                     "count": 20}],
}


@pytest.fixture
def room_b_file(tmp_path) -> Path:
    p = tmp_path / "room_b.json"
    p.write_text(json.dumps(ROOM_B))
    return p


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("pedmesh: error:") and "internal error" not in err[0], err
    return err[0]


def _parts(out: Path) -> list[str]:
    return sorted(str(p.relative_to(out)) for p in out.rglob("*.part*"))


# ---------------------------------------------------------------- item 2: ownership
def test_rerun_removes_only_pedmeshs_own_files(geometries_dir, tmp_path):
    out = tmp_path / "run"
    room = str(geometries_dir / "corridor_bottleneck.json")
    assert main(["run", room, "--out", str(out), "-q", "--t-end", "1"]) == 0
    (out / "report.part").write_text("the user's half-written report")
    (out / "draft.part.vtu").write_text("mine too")
    # pedmesh's own leftovers of a killed run, by their exact names
    for name in ("summary.json.part", "density.pvd.part", "pedestrians.pvd.part"):
        (out / name).write_text("partial")
    (out / "density" / "density_000042.part.vtu").write_text("partial")
    assert main(["run", room, "--model", "rdue", "--out", str(out), "-q", "--t-end", "1"]) == 0
    assert (out / "report.part").read_text() == "the user's half-written report"
    assert (out / "draft.part.vtu").read_text() == "mine too"
    assert _parts(out) == ["draft.part.vtu", "report.part"]
    assert json.loads((out / "summary.json").read_text())["model"] == "rdue"


# ---------------------------------------------------------------- item 3: full disk
class FullDisk:
    """A disk that fills up when :meth:`trip` is called: from then on pedmesh's summary
    cannot be written until space was freed in the run folder (the .lock's reserve given
    back or a .part file removed), as on a real full disk."""

    def __init__(self, monkeypatch) -> None:
        self.full = False
        self.used: int | None = None
        self.folder: Path | None = None
        original = output_module.atomic_write

        def atomic_write(path: Path, text: str) -> None:
            if self.full and self._used() >= self.used:
                raise OSError(errno.ENOSPC, ENOSPC_TEXT)  # as write() reports it: no name
            original(path, text)

        monkeypatch.setattr(output_module, "atomic_write", atomic_write)

    def _used(self) -> int:
        return sum(p.stat().st_size for p in self.folder.rglob("*")
                   if p.is_file() and (p.name == ".lock" or ".part" in p.name))

    def trip(self, folder: Path) -> None:
        if not self.full:
            self.folder = Path(folder)
            self.full = True
            self.used = self._used()

    def error(self, filename: str | None = None) -> OSError:
        return OSError(errno.ENOSPC, ENOSPC_TEXT, *([filename] if filename else []))


class _FailingFile:
    """A text file whose writes fail once the disk is full."""

    def __init__(self, f, disk: FullDisk, after: int) -> None:
        self._f, self._disk, self._left = f, disk, after

    def write(self, text):
        self._left -= 1
        if self._left < 0:
            self._disk.trip(Path(self._f.name).parent)
            raise self._disk.error()
        return self._f.write(text)

    def __getattr__(self, name):
        return getattr(self._f, name)


class _FailingSQL:
    """An SQLite connection whose inserts fail once the disk is full."""

    def __init__(self, con, disk: FullDisk, folder: Path, after: int) -> None:
        self._con, self._disk, self._folder, self._left = con, disk, folder, after

    def executemany(self, *args):
        self._left -= 1
        if self._left < 0:
            self._disk.trip(self._folder)
            raise sqlite3.OperationalError("database or disk is full")
        return self._con.executemany(*args)

    def __getattr__(self, name):
        return getattr(self._con, name)


def _inject(monkeypatch, disk: FullDisk, where: str) -> None:
    """Make the write of ``where`` fail with a full disk after a few good ones."""
    from pedmesh.io import vtk

    if where in ("evacuation.csv", "trajectories.txt"):
        attr = {"evacuation.csv": "_evac", "trajectories.txt": "_traj"}[where]
        method = "start" if where == "evacuation.csv" else "trajectory_frame"
        original = getattr(RunWriter, method)

        def wrapped(self, *args, **kwargs):
            first = getattr(self, attr) is None
            result = original(self, *args, **kwargs)
            if first and getattr(self, attr) is not None:
                setattr(self, attr, _FailingFile(getattr(self, attr), disk, after=10))
            return result

        monkeypatch.setattr(RunWriter, method, wrapped)
    elif where == "density.pvd":  # the collection's index, written through a .part file
        original_index = vtk.PVDWriter._write_index

        def write_index(self):
            if len(self.entries) >= 3:
                disk.trip(self.path.parent)
                self.path.with_name(self.path.name + ".part").write_text("<?xml")
                raise disk.error()
            original_index(self)

        monkeypatch.setattr(vtk.PVDWriter, "_write_index", write_index)
    elif where == "density frame":  # a frame's .vtu, written half
        original_frame = vtk._write_frame

        def write_frame(path, *args):
            if path.name.endswith("000002.vtu"):
                disk.trip(path.parent.parent)
                tmp = path.with_name(path.stem + ".part.vtu")
                tmp.write_text("<VTKFile")
                raise disk.error(str(tmp))
            return original_frame(path, *args)

        monkeypatch.setattr(vtk, "_write_frame", write_frame)
    elif where == "trajectories.sqlite":
        original_open = RunWriter._sql_open

        def sql_open(self, *args, **kwargs):
            original_open(self, *args, **kwargs)
            self._sql = _FailingSQL(self._sql, disk, self.dir, after=5)

        monkeypatch.setattr(RunWriter, "_sql_open", sql_open)
    else:  # pragma: no cover
        raise ValueError(where)


@pytest.mark.parametrize("model, where, named", [
    ("eos", "evacuation.csv", "evacuation.csv"),
    ("eos", "density.pvd", "density.pvd"),
    ("eos", "density frame", "density_000002.vtu"),
    ("sfm", "trajectories.txt", "trajectories.txt"),
    ("sfm", "trajectories.sqlite", "trajectories.sqlite"),
])
def test_full_disk_fails_naming_the_file(geometries_dir, tmp_path, monkeypatch, capsys,
                                         model, where, named):
    disk = FullDisk(monkeypatch)
    _inject(monkeypatch, disk, where)
    out = tmp_path / "full"
    status = main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--model", model,
                   "--out", str(out), "-q", "--t-end", "5"])
    line = _one_line_error(capsys)
    assert disk.full, "the fault was not reached"
    assert status == 2
    assert named in line and (ENOSPC_TEXT in line or "disk is full" in line), line
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "failed" and named in s["error"], s.get("error")
    assert run_status(out) == "failed"
    assert _parts(out) == []
    assert (out / ".lock").stat().st_size == 0  # the reserve is given back


@pytest.mark.parametrize("model, where, named", [
    ("eos", "density frame", "density_000002.vtu"),
    ("sfm", "trajectories.sqlite", "trajectories.sqlite"),
])
def test_full_disk_on_the_background_writer(geometries_dir, tmp_path, monkeypatch, capsys,
                                            background_writers, model, where, named):
    """On two threads the output is written on a thread of its own
    (pedmesh.run.background): its failed write ends the run the same way."""
    made = background_writers
    disk = FullDisk(monkeypatch)
    _inject(monkeypatch, disk, where)
    out = tmp_path / "full"
    status = main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--model", model,
                   "--out", str(out), "-q", "--t-end", "5", "--param", "threads=2"])
    line = _one_line_error(capsys)
    assert made and disk.full and status == 2
    assert named in line and (ENOSPC_TEXT in line or "disk is full" in line), line
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "failed" and named in s["error"], s.get("error")
    assert _parts(out) == [] and (out / ".lock").stat().st_size == 0


def test_full_disk_in_python_is_an_oserror_and_a_pedmesh_error(geometries_dir, tmp_path,
                                                               monkeypatch):
    disk = FullDisk(monkeypatch)
    _inject(monkeypatch, disk, "trajectories.sqlite")
    room = pedmesh.load_room(geometries_dir / "corridor_bottleneck.json")
    with pytest.raises(PedmeshError) as info:
        run_model(room, triangulate(room), "sfm", out_dir=tmp_path / "r", quiet=True,
                  t_end=3.0)
    assert isinstance(info.value, OSError) and info.value.errno == errno.ENOSPC
    assert info.value.filename.endswith("trajectories.sqlite")
    assert "\n" not in str(info.value)


def test_a_real_write_limit_fails_in_one_line(geometries_dir, tmp_path):
    """A real failed write (RLIMIT_FSIZE: files above 20 kB cannot be written) in VTK's
    writer: one line naming the frame, exit 2, summary failed, no .part left."""
    resource = pytest.importorskip("resource")
    out = tmp_path / "limited"
    cmd = [sys.executable, "-m", "pedmesh", "run",
           str(geometries_dir / "corridor_bottleneck.json"), "--model", "eos", "--out",
           str(out), "-q", "--t-end", "3"]
    env = {**os.environ, "PYTHONPATH": str(Path(pedmesh.__file__).parents[1])}
    # first without the limit (numba's caches are written then, not under the limit)
    assert subprocess.run(cmd, env=env, capture_output=True).returncode == 0

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, 20_000))

    r = subprocess.run(cmd, env=env, capture_output=True, text=True, preexec_fn=limit)
    err = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(err) == 1, r.stderr
    assert "cannot write" in err[0] and "density_0000" in err[0], err
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "failed" and "density_0000" in s["error"]
    assert _parts(out) == []


# ---------------------------------------------------------------- item 4: broken summary
BROKEN = {
    "truncated": lambda text: text[:100],
    "a list": lambda text: json.dumps([json.loads(text)]),
    "wrong types": lambda text: json.dumps({**json.loads(text), "settings": ["x"],
                                            "t_evac_90": "soon"}),
    "unknown status": lambda text: json.dumps({**json.loads(text), "status": 5}),
}


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory, geometries_dir) -> Path:
    out = tmp_path_factory.mktemp("finished") / "sfm"
    assert main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--out", str(out),
                 "-q", "--t-end", "1"]) == 0
    return out


def _broken_copy(finished_run: Path, where: Path, kind: str) -> Path:
    shutil.copytree(finished_run, where)
    s = where / "summary.json"
    s.write_text(BROKEN[kind](s.read_text()))
    return where


@pytest.mark.parametrize("kind", list(BROKEN))
def test_load_names_a_broken_summary(finished_run, tmp_path, kind):
    d = _broken_copy(finished_run, tmp_path / "run", kind)
    with pytest.raises(PedmeshError) as info:
        RunResult.load(d)
    msg = str(info.value)
    assert "\n" not in msg and str(d / "summary.json") in msg
    assert run_status(d) is None


@pytest.mark.parametrize("kind, rerun", [("truncated", False), ("a list", True),
                                         ("wrong types", False), ("wrong types", True)])
def test_compare_reruns_a_broken_run(geometries_dir, finished_run, tmp_path, capsys, kind,
                                     rerun):
    out = tmp_path / "cmp"
    out.mkdir()
    _broken_copy(finished_run, out / "sfm", kind)
    status = main(["compare", str(geometries_dir / "corridor_bottleneck.json"), "--models",
                   "sfm", "--out", str(out), "--t-end", "1", *(["--rerun"] if rerun else [])])
    err = capsys.readouterr().err
    assert status == 0, err
    assert "internal error" not in err
    assert "running (its summary is broken" in err or "reuse is off" in err, err
    assert RunResult.load(out / "sfm").finished


@pytest.mark.parametrize("kind", list(BROKEN))
def test_run_into_a_broken_run_folder(geometries_dir, finished_run, tmp_path, capsys, kind):
    room = str(geometries_dir / "corridor_bottleneck.json")
    # among the user's files: refused in one line naming the file; nothing is touched
    mine = _broken_copy(finished_run, tmp_path / "mine", kind)
    (mine / "notes.txt").write_text("mine")
    before = sorted(p.name for p in mine.iterdir())
    broken = (mine / "summary.json").read_text()
    assert main(["run", room, "--out", str(mine), "-q", "--t-end", "1"]) == 2
    line = _one_line_error(capsys)
    assert str(mine / "summary.json") in line and "notes.txt" in line
    assert sorted(p.name for p in mine.iterdir()) == before
    assert (mine / "summary.json").read_text() == broken
    # only pedmesh's files: an earlier (broken) run of its own, cleared and run again
    if kind == "truncated":
        d = _broken_copy(finished_run, tmp_path / "ours", kind)
        assert main(["run", room, "--model", "rdue", "--out", str(d), "-q",
                     "--t-end", "1"]) == 0
        assert RunResult.load(d).model == "rdue" and not (d / "exits.csv").exists()


def test_a_lone_foreign_summary_is_not_taken(geometries_dir, tmp_path, capsys):
    d = tmp_path / "theirs"
    d.mkdir()
    (d / "summary.json").write_text('{"total": 3}')  # someone else's summary, alone
    assert main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--out", str(d),
                 "-q", "--t-end", "1"]) == 2
    assert str(d / "summary.json") in _one_line_error(capsys)
    assert [p.name for p in d.iterdir()] == ["summary.json"]


# ---------------------------------------------------------------- item 6: exit names
def test_exit_names_with_commas_and_newlines(room_b_file, tmp_path):
    pd = pytest.importorskip("pandas")
    out = tmp_path / "b"
    assert main(["run", str(room_b_file), "--out", str(out), "-q", "--t-end", "30"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["n_evacuated"] == 20
    exits = pd.read_csv(out / "exits.csv")
    assert list(exits.columns) == ["id", "exit", "t"] and len(exits) == 20
    assert set(exits["exit"]) <= {DOOR_1, DOOR_2} and DOOR_1 in set(exits["exit"])
    for name in ("outflow.csv", "outflow_kernel.csv"):
        assert list(pd.read_csv(out / name).columns) == ["t", DOOR_1, DOOR_2], name
    res = RunResult.load(out)
    t, flows, names = res.outflow
    assert names == [DOOR_1, DOOR_2] and flows.shape == (len(t), 2)
    assert len(res.exit_times) == 20
    assert flows[1:].T @ np.diff(t) == pytest.approx(
        [s["exits"][DOOR_1], s["exits"][DOOR_2]], abs=0.5)
    # in memory the same
    mem = pedmesh.simulate(room_b_file, model="sfm", t_end=30.0)
    assert len(mem.exit_times) == 20 and mem.outflow[2] == [DOOR_1, DOOR_2]


def test_continuum_outflow_with_a_comma_in_an_exit_name(room_b_file, tmp_path):
    out = tmp_path / "b"
    assert main(["run", str(room_b_file), "--model", "rdue", "--out", str(out), "-q",
                 "--t-end", "2"]) == 0
    _, flows, names = RunResult.load(out).outflow
    assert names == [DOOR_1, DOOR_2] and flows.shape[1] == 2


# ---------------------------------------------------------------- item 8: room and mesh
def _room_b():
    return pedmesh.Room(ROOM_B["outline"], exits=ROOM_B["exits"],
                        start_areas=ROOM_B["start_areas"], name="B")


def test_a_room_is_refused_on_another_rooms_mesh(geometries_dir, tmp_path):
    room_b = _room_b()
    room_c = pedmesh.load_room(geometries_dir / "corridor_bottleneck.json")
    mesh_c = triangulate(room_c)
    for model in ("sfm", "eos"):
        with pytest.raises(ParameterError, match="made from room 'corridor_bottleneck', "
                                                 "not from room 'B'") as info:
            run_model(room_b, mesh_c, model, out_dir=tmp_path / model, quiet=True, t_end=1.0)
        assert "\n" not in str(info.value)
        assert not (tmp_path / model).exists()  # refused before anything is written
    with pytest.raises(ParameterError, match="made from room"):
        pedmesh.simulate(room_b, model="sfm", mesh=mesh_c, t_end=1.0)
    with pytest.raises(ParameterError, match="made from room"):
        pedmesh.build(room_b, model="eos", mesh=mesh_c)
    # the same room with another crowd runs on the mesh; the same name with other walls not
    fewer = room_c.with_changes(start_areas=[{"name": "few", "count": 5, "polygon":
                                              [[1, 1], [5, 1], [5, 5], [1, 5]]}])
    assert pedmesh.build(fewer, model="sfm", mesh=mesh_c).n_initial == 5
    wider = room_c.with_changes(outline=[[x * 1.1, y] for x, y in room_c.outline],
                                exits=[{"name": "end", "polyline": [[44.0, 0.0], [44.0, 6.0]]}],
                                measurement_lines=[], measurement_areas=[])
    with pytest.raises(ParameterError, match="walls, obstacles or exits differ"):
        pedmesh.build(wider, model="sfm", mesh=mesh_c)
    # a mesh made without a room: its exits and area must be the room's
    import dataclasses

    bare = dataclasses.replace(mesh_c, room=None, room_fingerprint=None)
    assert bare.room_fingerprint is None
    with pytest.raises(ParameterError, match="not those of room 'B'"):
        pedmesh.build(room_b, model="sfm", mesh=bare)
    assert pedmesh.build(room_c, model="sfm", mesh=bare).n_initial == 150


def test_density_at_refuses_another_mesh(geometries_dir, finished_run):
    room_c = pedmesh.load_room(geometries_dir / "corridor_bottleneck.json")
    mesh_c = triangulate(room_c)
    res = RunResult.load(finished_run)
    ft, rho, vel = res.density_at(0.0, mesh_c)
    assert ft == 0.0 and len(rho) == mesh_c.n_triangles
    others = [triangulate(_room_b()), triangulate(room_c, max_area=0.5),
              TriMesh(mesh_c.points + [0.1, 0.0], mesh_c.triangles)]  # same counts, moved
    for other in others:
        with pytest.raises(PedmeshError, match="not a frame of this mesh") as info:
            res.density_at(0.0, other)
        assert "\n" not in str(info.value) and "density_000000.vtu" in str(info.value)


# ---------------------------------------------------------------- item 13
def test_refused_folder_keeps_no_lock(geometries_dir, tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("precious")
    assert main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--out", str(out),
                 "-q", "--t-end", "1"]) == 2
    assert "not a pedmesh run directory" in _one_line_error(capsys)
    assert [p.name for p in out.iterdir()] == ["thesis.tex"]


def test_a_parameter_given_twice_is_refused(geometries_dir, tmp_path, capsys):
    from pedmesh.compare import parse_model_specs
    from pedmesh.parameters import parse_overrides

    out = tmp_path / "run"
    assert main(["run", str(geometries_dir / "corridor_bottleneck.json"), "--out", str(out),
                 "-q", "--t-end", "1", "--param", "A=1", "--param", "A=2"]) == 2
    line = _one_line_error(capsys)
    assert "'A' is given twice" in line and "A=1" in line and "A=2" in line
    assert not out.exists()
    with pytest.raises(ParameterError, match="'A' is given twice"):
        parse_overrides(["A=1500", " A = 1500"])
    with pytest.raises(ParameterError, match="'c0' is given twice"):
        parse_model_specs("pw:c0=0.5:c0=0.6")
    assert parse_overrides(["A=1", "B=2"]) == {"A": 1.0, "B": 2.0}
