"""Run output written as the run goes, so an interrupted run keeps what it computed.

The files of the output directory are listed, with what each holds, in
:data:`OUTPUT_FILES` (``pedmesh run --help`` prints the same list). ``summary.json`` is
written at the start (status ``running``) and rewritten at the end with status
``finished``, ``stopped at t_end``, ``interrupted`` or ``failed`` (with the error); a
``running`` run whose process is gone reads as ``interrupted`` (:func:`run_status`). The
time series are flushed as written. ``.lock`` is held (``flock``) while a run writes into
the directory.

A run owns its directory: it refuses a non-empty directory that is not a pedmesh run,
holds a lock while it runs (a second run into the same directory is an error), and starts
clean, removing the files of an earlier pedmesh run there.
"""

from __future__ import annotations

import fnmatch
import hashlib
import json
import math
import os
import shutil
import sqlite3
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from .._version import __version__
from ..analysis.evacuation import evacuation_times, evacuation_times_from_curve
from ..errors import PedmeshError
from ..io.vtk import PVDWriter

#: the files of a run folder and what each holds (``pedmesh run --help`` and the docs print
#: this list); "(particle models)" marks those only particle models write
OUTPUT_FILES: dict[str, str] = {
    "summary.json": "model, status, n_initial, n_evacuated, t_evac_50/90/100 [s], steps, "
                    "dt, wall time, every parameter used with its unit, the run's "
                    "settings (room file hash, model, preset, overrides, t_end, mesh), and "
                    "the crowd-safety measures (\"safety\", see docs/safety.md)",
    "evacuation.csv": "t,evacuated (cumulative number out), every sample_interval (0.1 s)",
    "outflow.csv": "t and the flow [ped/s] through each exit, the mean since the previous "
                   "row (crossings, or the integrated boundary flux of a continuum model)",
    "density.pvd": "density on the mesh [ped/m^2] (and velocity [m/s]), one frame per "
                   "output_interval",
    "pedestrians.pvd": "(particle models) positions with velocity, speed, local density",
    "trajectories.txt": "(particle models) id frame x y [m] at the trajectory rate, for "
                        "PedPy's load_trajectory_from_txt; a leaver's last row is on the exit",
    "trajectories.sqlite": "(particle models) the same in JuPedSim's SQLite format (with the "
                           "walkable area), for pedpy.load_trajectory_from_jupedsim_sqlite",
    "exits.csv": "(particle models) id,exit,t of everyone who left",
    "safety.vtu": "the crowd-safety maps per cell: peak density on 1 m^2 [ped/m^2] and its "
                  "time, worst Fruin level of service (0-5 for A-F, walkway and queuing), "
                  "time above 2, 4, 6 /m^2 [s], the social force model's max crowd "
                  "pressure [1/s^2]; the numbers are in summary.json under \"safety\"",
}

try:  # POSIX advisory locks; elsewhere the process id in summary.json is checked
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    fcntl = None

__all__ = ["OUTPUT_FILES", "RunWriter", "RunFolderError", "evacuation_times",
           "evacuation_times_from_curve", "file_sha256", "run_status", "RUN_FILES"]

#: names (glob patterns) of everything a run writes into its directory
RUN_FILES = ("summary.json", "evacuation.csv", "outflow.csv", "outflow_kernel.csv",
             "exits.csv", "density.pvd", "density", "pedestrians.pvd", "pedestrians",
             "trajectories.txt", "trajectories.sqlite", "trajectories.sqlite-journal",
             "safety.vtu", ".lock", "*.part")
LOCK = ".lock"


class RunFolderError(PedmeshError):
    """The output directory cannot be used for this run (not a run, or in use)."""


def file_sha256(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes (the room file a run was made from)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _atomic_write(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".part")
    try:
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)  # never leave a .part behind (e.g. a full disk)
        raise


def _is_run_file(name: str) -> bool:
    return any(fnmatch.fnmatchcase(name, pat) for pat in RUN_FILES)


def _read_summary(d: Path) -> dict | None:
    try:
        data = json.loads((d / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and "pedmesh_version" in data else None


def _lock_is_held(d: Path) -> bool | None:
    """Whether another process holds the directory's lock (None where locks are unknown)."""
    if fcntl is None or not (d / LOCK).exists():
        return None
    with open(d / LOCK, "a+") as f:
        try:
            fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return True
        fcntl.flock(f.fileno(), fcntl.LOCK_UN)
        return False


def _pid_alive(pid: Any) -> bool:
    try:
        os.kill(int(pid), 0)
    except (OSError, TypeError, ValueError):
        return False
    return True


def run_status(path: str | Path, summary: Mapping[str, Any] | None = None) -> str | None:
    """The status of the run in ``path``: as recorded, except that a ``running`` run whose
    process is gone (its lock free, or its process id dead) reads as ``interrupted``.
    ``None`` if ``path`` holds no run."""
    d = Path(path)
    s = _read_summary(d) if summary is None else summary
    if s is None:
        return None
    status = s.get("status")
    if status == "running":
        held = _lock_is_held(d)
        if held is False or (held is None and not _pid_alive(s.get("pid"))):
            return "interrupted"
    return status


def claim_run_dir(out_dir: str | Path):
    """Make ``out_dir`` this run's: refuse a non-empty directory that is not a pedmesh run
    and one another run is writing into; remove an earlier run's files; take the lock.
    Returns the open lock file (keep it open while the run writes)."""
    d = Path(out_dir)
    if d.exists() and not d.is_dir():
        raise RunFolderError(f"{d}: exists and is not a directory")
    d.mkdir(parents=True, exist_ok=True)
    lock = open(d / LOCK, "a+")
    if fcntl is not None:
        try:
            fcntl.flock(lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            lock.close()
            raise RunFolderError(f"{d}: another pedmesh run is writing into this directory; "
                                 "wait for it or choose another --out") from None
    try:
        entries = [e for e in d.iterdir() if e.name != LOCK]
        prev = _read_summary(d)
        if entries and prev is None:
            raise RunFolderError(f"{d}: not empty and not a pedmesh run directory; choose "
                                 "another --out (pedmesh does not write into other files)")
        if prev is not None and fcntl is None and prev.get("status") == "running" \
                and prev.get("pid") != os.getpid() and _pid_alive(prev.get("pid")):
            raise RunFolderError(f"{d}: another pedmesh run (process {prev.get('pid')}) is "
                                 "writing into this directory")
        for e in entries:  # the earlier run's outputs go; other files stay
            if _is_run_file(e.name):
                if e.is_dir() and not e.is_symlink():
                    shutil.rmtree(e)
                else:
                    e.unlink()
    except BaseException:
        lock.close()
        raise
    return lock


def _clean(obj: Any) -> Any:
    """JSON-safe copy: numpy scalars to Python, NaN/inf to None."""
    if isinstance(obj, Mapping):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _clean(obj.tolist())
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        f = float(obj)
        return f if math.isfinite(f) else None
    return obj


class RunWriter:
    """Incremental writer of one run's output directory (see module docstring).

    Creating it claims the directory (:func:`claim_run_dir`) and writes ``summary.json``
    with status ``running``; :meth:`finish` closes every file, writes the final summary and
    releases the lock.
    """

    def __init__(self, out_dir: str | Path, header: Mapping[str, Any], *,
                 exit_names: Sequence[str] = ()) -> None:
        self.dir = Path(out_dir)
        self._lock = claim_run_dir(self.dir)
        self.header = dict(header)
        self.header.setdefault("pedmesh_version", __version__)
        self.header["pid"] = os.getpid()
        self._summary_path = self.dir / "summary.json"
        self._evac = self._outflow = self._traj = None
        self._sql: sqlite3.Connection | None = None
        self._extra: dict = {}
        self._density: PVDWriter | None = None
        self._peds: PVDWriter | None = None
        self.frames = 0
        self.exit_names = list(exit_names)
        try:
            self._write_summary({**self.header, "status": "running"})
        except BaseException:
            self._lock.close()
            raise

    def start(self, header: Mapping[str, Any] | None = None) -> None:
        """Open the time series (after the model was built); ``header`` adds to the
        summary (e.g. the model's resolved parameters)."""
        if header:
            self.header.update(header)
            self._write_summary({**self.header, "status": "running"})
        self._evac = open(self.dir / "evacuation.csv", "w", encoding="utf-8")
        self._evac.write("t,evacuated\n")
        self._evac.flush()
        self._outflow = open(self.dir / "outflow.csv", "w", encoding="utf-8")
        self._outflow.write("t," + ",".join(self.exit_names) + "\n")
        self._outflow.flush()

    # ------------------------------------------------------------------ pieces
    def _write_summary(self, data: Mapping[str, Any]) -> None:
        _atomic_write(self._summary_path, json.dumps(_clean(data), indent=2) + "\n")

    def sample(self, t: float, evacuated: float) -> None:
        """Append a row to evacuation.csv."""
        val = f"{int(evacuated)}" if float(evacuated).is_integer() else f"{evacuated:.6g}"
        self._evac.write(f"{t:.6f},{val}\n")
        self._evac.flush()

    def outflow(self, t: float, flows: Sequence[float]) -> None:
        """Append a row to outflow.csv (flow [ped/s] per exit)."""
        if self._outflow is not None:
            self._outflow.write(f"{t:.6f}," + ",".join(f"{f:.9g}" for f in flows) + "\n")
            self._outflow.flush()

    def append_rows(self, name: str, header: str, rows: Sequence[str]) -> None:
        """Append text rows to a CSV file of the run (created with ``header``)."""
        path = self.dir / name
        if name not in self._extra:
            self._extra[name] = open(path, "w", encoding="utf-8")
            self._extra[name].write(header + "\n")
        f = self._extra[name]
        if rows:
            f.write("\n".join(rows) + "\n")
        f.flush()

    def density_frame(self, t: float, mesh, point_data=None, cell_data=None) -> None:
        """Add a frame to density.pvd."""
        if self._density is None:
            self._density = PVDWriter(self.dir / "density.pvd")
        self._density.write_mesh(t, mesh, point_data, cell_data)

    def pedestrian_frame(self, t: float, points: np.ndarray,
                         data: Mapping[str, np.ndarray]) -> None:
        """Add a frame to pedestrians.pvd."""
        if self._peds is None:
            self._peds = PVDWriter(self.dir / "pedestrians.pvd")
        self._peds.write_points(t, points, data)

    def trajectory_frame(self, frame: int, ids: np.ndarray, points: np.ndarray,
                         frame_rate: float, description: str, *,
                         orientation: np.ndarray | None = None,
                         walkable_wkt: str | None = None) -> None:
        """Append one frame to trajectories.txt (PedPy text format) and to
        trajectories.sqlite (JuPedSim's schema, version 2). ``orientation`` (n, 2): unit
        heading of each row (JuPedSim's ori_x/ori_y; zero where unknown);
        ``walkable_wkt``: the walkable area, stored with the first frame."""
        ids = np.asarray(ids, np.int64)
        points = np.asarray(points, float).reshape(-1, 2)
        if self._traj is None:
            self._traj = open(self.dir / "trajectories.txt", "w", encoding="utf-8")
            self._traj.write(f"# pedmesh {__version__}: {description}\n")
            self._traj.write(f"# framerate: {frame_rate:g} fps "
                             "(frame k is at t = k / framerate s)\n")
            self._traj.write("# unit: x/m, y/m (coordinates in metres)\n")
            self._traj.write("# id frame x y\n")
            self._sql_open(frame_rate, walkable_wkt)
        lines = "".join(f"{int(i)} {frame} {p[0]:.4f} {p[1]:.4f}\n" for i, p in zip(ids, points))
        self._traj.write(lines)
        self._traj.flush()
        ori = np.zeros_like(points) if orientation is None else np.asarray(orientation, float)
        con = self._sql
        con.executemany("INSERT INTO trajectory_data VALUES (?, ?, ?, ?, ?, ?)",
                        zip([frame] * len(ids), ids.tolist(), points[:, 0].tolist(),
                            points[:, 1].tolist(), ori[:, 0].tolist(), ori[:, 1].tolist()))
        con.execute("INSERT INTO frame_data VALUES (?, ?)", (frame, self._geo_hash))
        con.commit()

    def _sql_open(self, frame_rate: float, walkable_wkt: str | None) -> None:
        """Create trajectories.sqlite in JuPedSim's schema (version 2: trajectory_data with
        orientation, metadata with version, fps and bounds, geometry as WKT by hash,
        frame_data naming each frame's geometry), which PedPy 1.x and JuPedSim read."""
        import shapely

        con = sqlite3.connect(self.dir / "trajectories.sqlite")
        con.execute("PRAGMA synchronous=OFF")  # survives a killed process; no fsync per frame
        con.execute("CREATE TABLE trajectory_data (frame INTEGER NOT NULL, id INTEGER NOT NULL,"
                    " pos_x REAL NOT NULL, pos_y REAL NOT NULL, ori_x REAL NOT NULL,"
                    " ori_y REAL NOT NULL)")
        con.execute("CREATE TABLE metadata (key TEXT NOT NULL UNIQUE PRIMARY KEY,"
                    " value TEXT NOT NULL)")
        con.execute("CREATE TABLE geometry (hash INTEGER NOT NULL, wkt TEXT NOT NULL)")
        con.execute("CREATE UNIQUE INDEX geometry_hash ON geometry(hash)")
        con.execute("CREATE TABLE frame_data (frame INTEGER NOT NULL,"
                    " geometry_hash INTEGER NOT NULL)")
        con.execute("CREATE INDEX frame_id_idx ON trajectory_data(frame, id)")
        wkt = walkable_wkt or "POLYGON EMPTY"
        # a stable 63-bit hash (Python's hash() of a str changes between processes)
        self._geo_hash = int.from_bytes(hashlib.sha256(wkt.encode()).digest()[:8], "big") >> 1
        con.execute("INSERT INTO geometry VALUES (?, ?)", (self._geo_hash, wkt))
        meta = {"version": "2", "fps": repr(float(frame_rate)), "generator":
                f"pedmesh {__version__}"}
        if walkable_wkt:
            xmin, ymin, xmax, ymax = shapely.from_wkt(walkable_wkt).bounds
            meta.update(xmin=repr(xmin), xmax=repr(xmax), ymin=repr(ymin), ymax=repr(ymax))
        con.executemany("INSERT INTO metadata VALUES (?, ?)", meta.items())
        con.commit()
        self._sql = con

    def close_files(self) -> None:
        """Close every open file (idempotent); errors of one do not keep others open."""
        first: BaseException | None = None
        for f in (self._evac, self._outflow, self._traj, *self._extra.values()):
            try:
                if f is not None and not f.closed:
                    f.close()
            except OSError as exc:
                first = first or exc
        for w in (self._density, self._peds):
            try:
                if w is not None:
                    w.close()
            except OSError as exc:
                first = first or exc
        if self._sql is not None:
            try:
                self._sql.close()
            except sqlite3.Error as exc:
                first = first or exc
            self._sql = None
        if first is not None:
            raise first

    def finish(self, **summary: Any) -> dict[str, Any]:
        """Close the files, write the final summary and release the directory; returns
        the summary. If closing a file fails (a full disk), the run is marked failed."""
        try:
            self.close_files()
        except (OSError, sqlite3.Error) as exc:
            if summary.get("status") != "failed":
                summary = {**summary, "status": "failed", "error": f"writing output: {exc}"}
        data = {**self.header, **summary}
        try:
            self._write_summary(data)
        finally:
            self._lock.close()
        return _clean(data)
