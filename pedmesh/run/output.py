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
clean, removing the files of an earlier pedmesh run there, by their exact names
(:data:`RUN_FILES`); every other file stays. A folder whose ``summary.json`` is broken
(truncated, not a JSON object, wrong-typed fields) counts as an earlier pedmesh run only
if everything else in it is pedmesh's; otherwise it is refused, naming the file.

Writing never leaves a half-done state unsaid: a failed write (a full disk, ...) raises
:class:`OutputWriteError` naming the file, the run's temporary files (``*.part``) are
removed and the summary says ``failed`` with the error. While a run writes, ``.lock``
holds a small reserve of disk space (:data:`RESERVE_BYTES`) that is given back to write
the final summary when the disk is full.
"""

from __future__ import annotations

import csv
import errno
import hashlib
import io
import json
import os
import sqlite3
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from .._version import __version__
from ..analysis.evacuation import evacuation_times, evacuation_times_from_curve
from ..io.files import temporary_beside
from ..errors import PedmeshError
from ..io.vtk import PVDWriter
from ..io import run_folder as F
from ._rows import format_rows
from ..io.run_folder import (LOCK, OUTPUT_FILES, RUN_FILES, STATUSES, TEMP_FILES,
                     BrokenSummaryError, RunFolderError, atomic_write, is_run_file,
                     json_safe, load_summary, pid_alive, read_summary, remove_frames,
                     run_status, summary_problem, take_lock)

__all__ = ["OUTPUT_FILES", "RunWriter", "RunFolderError", "BrokenSummaryError",
           "OutputWriteError", "evacuation_times", "evacuation_times_from_curve",
           "file_sha256", "run_status", "read_summary", "load_summary", "summary_problem",
           "RUN_FILES", "TEMP_FILES", "STATUSES", "RESERVE_BYTES", "check_writable",
           "write_error", "temporary_beside"]

#: [bytes] disk space held in .lock while a run writes, given back to write the final
#: summary on a full disk
RESERVE_BYTES = 64 * 1024


class OutputWriteError(PedmeshError, OSError):
    """Writing a run's output failed (a full disk, a file size limit, ...). An
    :class:`OSError` too, with ``errno`` (``ENOSPC`` on a full disk), ``strerror`` and
    ``filename``, the file that could not be written."""

    def __str__(self) -> str:
        return f"cannot write {self.filename}: {self.strerror}"


def _final_name(name: str | os.PathLike) -> str:
    """The file a temporary file stands for: ``x.part`` -> ``x``, ``x.part.vtu`` ->
    ``x.vtu``."""
    p = Path(name)
    if p.name.endswith(".part"):
        return str(p.with_name(p.name[:-5]))
    if ".part." in p.name:
        return str(p.with_name(p.name.replace(".part.", ".", 1)))
    return str(name)


def _write_error(path: str | os.PathLike, exc: BaseException) -> OutputWriteError:
    """``exc`` (an OSError or an SQLite error) as an :class:`OutputWriteError` naming the
    file (the error's own file name if it has one, else ``path``)."""
    if isinstance(exc, OutputWriteError):
        return exc
    if isinstance(exc, sqlite3.Error):
        reason = str(exc) or type(exc).__name__
        code = errno.ENOSPC if "full" in reason else None
        name = path
    else:
        reason = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
        code = getattr(exc, "errno", None)
        name = getattr(exc, "filename", None) or path
    return OutputWriteError(code, reason, _final_name(name))


def check_writable(path: str | os.PathLike) -> None:
    """Make sure the file ``path`` can be written before the work that produces it (a
    report, an animation): its folder is made if missing, and a probe next to it (a new
    temporary file, :func:`temporary_beside`) created and removed.
    :class:`OutputWriteError` naming ``path`` if not."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        if path.is_dir():
            raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), str(path))
        if path.exists() and not os.access(path, os.W_OK):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(path))
        temporary_beside(path).unlink()
    except OSError as exc:
        raise OutputWriteError(exc.errno, exc.strerror or str(exc), str(path)) from None


def write_error(path: str | os.PathLike, exc: BaseException) -> OutputWriteError:
    """``exc``, an OSError raised while writing ``path``, as an :class:`OutputWriteError`
    naming the file."""
    return _write_error(path, exc)


def _one_word(name: str) -> str:
    """``name`` as one whitespace-free column of trajectories.txt: whitespace, control
    characters and '%' percent-encoded (``urllib.parse.unquote`` gives the name back);
    other characters, Unicode included, as they are."""
    return "".join("".join(f"%{b:02X}" for b in c.encode("utf-8"))
                   if (c.isspace() or c == "%" or not c.isprintable()) else c for c in name)


def file_sha256(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes (the room file a run was made from)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def claim_run_dir(out_dir: str | Path):
    """Make ``out_dir`` this run's: refuse a non-empty directory that is not a pedmesh run
    and one another run is writing into; remove an earlier run's files; take the lock.
    Returns the open lock file (keep it open while the run writes)."""
    d = Path(out_dir)
    if d.exists() and not d.is_dir():
        raise RunFolderError(f"{d}: exists and is not a directory")
    d.mkdir(parents=True, exist_ok=True)
    had_lock = (d / LOCK).exists()
    lock = take_lock(d)
    if lock is None:
        raise RunFolderError(f"{d}: another pedmesh run is writing into this directory; "
                             "wait for it or choose another --out")
    try:
        entries = [e for e in d.iterdir() if e.name != LOCK]
        prev, problem = read_summary(d)
        others = sorted(e.name for e in entries if not is_run_file(e.name))
        if entries and prev is None and problem is None:
            raise RunFolderError(f"{d}: not empty and not a pedmesh run directory (it holds "
                                 f"'{(others or [entries[0].name])[0]}'); choose another "
                                 "--out (pedmesh does not write into other files)")
        if problem is not None and (others or not (had_lock or len(entries) > 1)):
            # a broken summary among other files: not provably pedmesh's
            what = f"the folder also holds '{others[0]}'" if others else \
                "nothing else of a pedmesh run is there"
            raise BrokenSummaryError(f"{d / F.SUMMARY}: not a pedmesh run summary "
                                     f"({problem}) and {what}; choose another --out or "
                                     "remove the folder")
        if prev is not None and not F.locks_known() and prev.get("status") == "running" \
                and prev.get("pid") != os.getpid() and pid_alive(prev.get("pid")):
            raise RunFolderError(f"{d}: another pedmesh run (process {prev.get('pid')}) is "
                                 "writing into this directory")
        for e in entries:  # the earlier run's outputs go; other files stay
            if is_run_file(e.name):
                if e.is_dir() and not e.is_symlink():
                    remove_frames(e)
                else:
                    e.unlink()
    except BaseException:
        lock.close()
        if not had_lock:  # a refused folder keeps nothing of ours
            (d / LOCK).unlink(missing_ok=True)
        raise
    return lock


def _csv_line(fields: Sequence[Any]) -> str:
    """One CSV line (the csv module's quoting: a name with a comma, a quote or a newline is
    quoted)."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(fields)
    return buf.getvalue()


#: rows of one multi-row INSERT of trajectories.sqlite (6 values each: well below SQLite's
#: limit of 32,766 bound values per statement)
_INSERT_ROWS = 256


def _insert_rows(con: sqlite3.Connection, table: str, width: int, frame: int,
                 ids: np.ndarray, *columns: np.ndarray) -> None:
    """Insert the rows ``(frame, id, *columns)`` into ``table`` in their order, as
    statements of :data:`_INSERT_ROWS` rows each (``INSERT ... VALUES (...), (...)``: the
    same rows, rowids and file as one INSERT per row, in half the time)."""
    n = len(ids)
    if n == 0:
        return
    flat = np.empty((n, width), object)
    flat[:, 0] = frame
    flat[:, 1] = ids.tolist()
    for k, c in enumerate(columns):
        flat[:, 2 + k] = np.asarray(c).tolist()
    values = flat.ravel().tolist()
    row = "(" + ", ".join("?" * width) + ")"
    full, rest = divmod(n, _INSERT_ROWS)
    step = width * _INSERT_ROWS
    if full:
        con.executemany(f"INSERT INTO {table} VALUES " + ", ".join([row] * _INSERT_ROWS),
                        [values[k * step:(k + 1) * step] for k in range(full)])
    if rest:
        con.executemany(f"INSERT INTO {table} VALUES " + ", ".join([row] * rest),
                        [values[full * step:]])


class RunWriter:
    """Incremental writer of one run's output directory (see module docstring).

    Creating it claims the directory (:func:`claim_run_dir`) and writes ``summary.json``
    with status ``running``; :meth:`finish` closes every file, writes the final summary and
    releases the lock. A write that fails raises :class:`OutputWriteError` naming the file.
    """

    def __init__(self, out_dir: str | Path, header: Mapping[str, Any], *,
                 exit_names: Sequence[str] = ()) -> None:
        self.dir = Path(out_dir)
        try:
            self._lock = claim_run_dir(self.dir)
        except PedmeshError:
            raise
        except OSError as exc:  # (a folder that cannot be made or written: named)
            raise OutputWriteError(exc.errno, exc.strerror or str(exc),
                                   str(exc.filename or self.dir)) from None
        self._reserve()
        self.header = dict(header)
        self.header.setdefault("pedmesh_version", __version__)
        self.header["pid"] = os.getpid()
        self._summary_path = self.dir / F.SUMMARY
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
            self._release_reserve()
            self._lock.close()
            raise

    # ------------------------------------------------------------------ disk reserve
    def _reserve(self) -> None:
        """Hold :data:`RESERVE_BYTES` of disk space in .lock (best effort)."""
        try:
            fd = self._lock.fileno()
            if hasattr(os, "posix_fallocate"):
                os.posix_fallocate(fd, 0, RESERVE_BYTES)
            elif os.fstat(fd).st_size < RESERVE_BYTES:
                os.pwrite(fd, bytes(RESERVE_BYTES), 0)
        except (OSError, AttributeError):  # a full disk already, or no such call
            pass

    def _release_reserve(self) -> None:
        try:
            self._lock.truncate(0)
        except (OSError, ValueError):
            pass

    def _remove_temporaries(self) -> None:
        """Remove pedmesh's own ``.part`` files, by their exact names (a failed write's
        leftovers; this frees their space too). SQLite's journal is SQLite's to remove."""
        for name in TEMP_FILES:
            if name.endswith(".part"):
                (self.dir / name).unlink(missing_ok=True)
        for sub in (F.DENSITY_DIR, F.PEDESTRIANS_DIR):
            d = self.dir / sub
            if d.is_dir():
                for e in d.iterdir():
                    if F.FRAME_TEMP.fullmatch(e.name):
                        e.unlink(missing_ok=True)

    def start(self, header: Mapping[str, Any] | None = None) -> None:
        """Open the time series (after the model was built); ``header`` adds to the
        summary (e.g. the model's resolved parameters)."""
        if header:
            self.header.update(header)
            self._write_summary({**self.header, "status": "running"})
        self._evac = self._open(F.EVACUATION, "t,evacuated\n")
        self._outflow = self._open(F.OUTFLOW, _csv_line(["t", *self.exit_names]))

    # ------------------------------------------------------------------ pieces
    def _open(self, name: str, header: str):
        """Open one of the run's text files for writing, with its header written."""
        path = self.dir / name
        try:
            f = open(path, "w", encoding="utf-8", newline="")
            try:
                f.write(header)
                f.flush()
            except BaseException:
                f.close()
                raise
        except OSError as exc:
            raise _write_error(path, exc) from None
        return f

    @staticmethod
    def _append(f, text: str) -> None:
        try:
            f.write(text)
            f.flush()
        except OSError as exc:
            raise _write_error(f.name, exc) from None

    def _write_summary(self, data: Mapping[str, Any]) -> None:
        try:
            atomic_write(self._summary_path, json.dumps(json_safe(data), indent=2) + "\n")
        except OSError as exc:
            raise _write_error(self._summary_path, exc) from None

    def call(self, fn, *args: Any, **kwargs: Any) -> None:
        """``fn(self, *args, **kwargs)``: output that is first computed from the model's
        state (e.g. a kernel average) and then written with this writer's methods. A
        background writer (:mod:`pedmesh.run.background`) makes the call on its own
        thread, in order with the other writes, so ``fn`` must use its arguments and
        nothing the model changes as it steps."""
        fn(self, *args, **kwargs)

    def sample(self, t: float, evacuated: float) -> None:
        """Append a row to evacuation.csv."""
        val = f"{int(evacuated)}" if float(evacuated).is_integer() else f"{evacuated:.6g}"
        self._append(self._evac, f"{t:.6f},{val}\n")

    def outflow(self, t: float, flows: Sequence[float]) -> None:
        """Append a row to outflow.csv (flow [ped/s] per exit)."""
        if self._outflow is not None:
            self._append(self._outflow,
                         f"{t:.6f}," + ",".join(f"{f:.9g}" for f in flows) + "\n")

    def append_rows(self, name: str, header: Sequence[str] | str,
                    rows: Sequence[Sequence[Any] | str]) -> None:
        """Append rows to a CSV file of the run (created with ``header``). A header or row
        given as a sequence of fields is written with the csv module (names with a comma,
        a quote or a newline are quoted); one given as a string is written as it is."""
        if name not in self._extra:
            self._extra[name] = self._open(
                name, header + "\n" if isinstance(header, str) else _csv_line(header))
        if rows:
            self._append(self._extra[name], "".join(
                r + "\n" if isinstance(r, str) else _csv_line(r) for r in rows))

    def density_frame(self, t: float, mesh, point_data=None, cell_data=None) -> None:
        """Add a frame to density.pvd."""
        path = self.dir / F.DENSITY_PVD
        try:
            if self._density is None:
                self._density = PVDWriter(path)
            self._density.write_mesh(t, mesh, point_data, cell_data)
        except OSError as exc:
            raise _write_error(path, exc) from None

    def pedestrian_frame(self, t: float, points: np.ndarray,
                         data: Mapping[str, np.ndarray]) -> None:
        """Add a frame to pedestrians.pvd."""
        path = self.dir / F.PEDESTRIANS_PVD
        try:
            if self._peds is None:
                self._peds = PVDWriter(path)
            self._peds.write_points(t, points, data)
        except OSError as exc:
            raise _write_error(path, exc) from None

    def trajectory_frame(self, frame: int, ids: np.ndarray, points: np.ndarray,
                         frame_rate: float, description: str, *,
                         orientation: np.ndarray | None = None,
                         walkable_wkt: str | None = None, z: np.ndarray | None = None,
                         place: Sequence[str] | None = None) -> None:
        """Append one frame to trajectories.txt (PedPy text format) and to
        trajectories.sqlite (JuPedSim's schema, version 2). ``orientation`` (n, 2): unit
        heading of each row (JuPedSim's ori_x/ori_y; zero where unknown);
        ``walkable_wkt``: the walkable area, stored with the first frame. A building's
        rows also carry their height ``z`` [m] and the level or stair they are on
        (``place``): two more columns of trajectories.txt and the table ``place_data``
        (frame, id, z, place) of trajectories.sqlite (the plan x, y stay in
        trajectory_data; :func:`pedmesh.analysis.level_trajectories` takes one level's rows
        for PedPy)."""
        ids = np.asarray(ids, np.int64)
        points = np.asarray(points, float).reshape(-1, 2)
        building = z is not None
        if self._traj is None:
            self._traj = self._open(
                F.TRAJECTORIES_TXT,
                f"# pedmesh {__version__}: {description}\n"
                f"# framerate: {frame_rate:g} fps (frame k is at t = k / framerate s)\n"
                + ("# unit: x/m, y/m, z/m (plan coordinates and height in metres; place: "
                   "the level or stair, a space, tab, newline or % written %XX)\n"
                   "# id frame x y z place\n" if building else
                   "# unit: x/m, y/m (coordinates in metres)\n# id frame x y\n"))
            sql_path = self.dir / F.TRAJECTORIES_SQLITE
            try:
                self._sql_open(frame_rate, walkable_wkt, building)
            except (OSError, sqlite3.Error) as exc:
                raise _write_error(sql_path, exc) from None
        if building:
            z = np.asarray(z, float).reshape(-1)
            names = {w: _one_word(w) for w in set(place)}
            lines = "".join(f"{int(i)} {frame} {p[0]:.4f} {p[1]:.4f} {h:.4f} {names[w]}\n"
                            for i, p, h, w in zip(ids, points, z, place))
        else:  # compiled, the same bytes as Python's f"{x:.4f}" (None: left to Python)
            lines = format_rows(ids, frame, points)
            if lines is None:
                lines = "".join(f"{i} {frame} {x:.4f} {y:.4f}\n"
                                for i, x, y in zip(ids.tolist(), points[:, 0].tolist(),
                                                   points[:, 1].tolist()))
        self._append(self._traj, lines)
        ori = np.zeros_like(points) if orientation is None else np.asarray(orientation, float)
        con = self._sql
        try:
            _insert_rows(con, "trajectory_data", 6, frame, ids, points[:, 0], points[:, 1],
                         ori[:, 0], ori[:, 1])
            if building:
                con.executemany("INSERT INTO place_data VALUES (?, ?, ?, ?)",
                                zip([frame] * len(ids), ids.tolist(), z.tolist(), list(place)))
            con.execute("INSERT INTO frame_data VALUES (?, ?)", (frame, self._geo_hash))
            con.commit()
        except (OSError, sqlite3.Error) as exc:
            raise _write_error(self.dir / F.TRAJECTORIES_SQLITE, exc) from None

    def _sql_open(self, frame_rate: float, walkable_wkt: str | None,
                  building: bool = False) -> None:
        """Create trajectories.sqlite in JuPedSim's schema (version 2: trajectory_data with
        orientation, metadata with version, fps and bounds, geometry as WKT by hash,
        frame_data naming each frame's geometry), which PedPy 1.x and JuPedSim read."""
        import shapely

        con = sqlite3.connect(self.dir / F.TRAJECTORIES_SQLITE, check_same_thread=False)
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
        if building:
            con.execute("CREATE TABLE place_data (frame INTEGER NOT NULL, id INTEGER NOT NULL,"
                        " z REAL NOT NULL, place TEXT NOT NULL)")
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
        """Close every open file (idempotent); errors of one do not keep others open. The
        first error is raised, as an :class:`OutputWriteError` naming its file."""
        first: BaseException | None = None
        for f in (self._evac, self._outflow, self._traj, *self._extra.values()):
            try:
                if f is not None and not f.closed:
                    f.close()
            except OSError as exc:
                first = first or _write_error(f.name, exc)
        for w in (self._density, self._peds):
            try:
                if w is not None:
                    w.close()
            except OSError as exc:
                first = first or _write_error(w.path, exc)
        if self._sql is not None:
            try:
                self._sql.close()
            except sqlite3.Error as exc:
                first = first or _write_error(self.dir / F.TRAJECTORIES_SQLITE, exc)
            self._sql = None
        if first is not None:
            raise first

    def finish(self, **summary: Any) -> dict[str, Any]:
        """Close the files, write the final summary and release the directory; returns
        the summary. If closing a file fails (a full disk), the run is marked failed.
        Pedmesh's temporary files are removed; if the summary cannot be written (a full
        disk), the space held in .lock is given back and it is written again."""
        try:
            self.close_files()
        except OSError as exc:
            if summary.get("status") != "failed":
                summary = {**summary, "status": "failed", "error": str(exc)}
        data = {**self.header, **summary}
        try:
            self._remove_temporaries()
        except OSError:
            pass
        try:
            try:
                self._write_summary(data)
            except OutputWriteError:
                self._release_reserve()
                self._write_summary(data)
        finally:
            self._release_reserve()
            self._lock.close()
        return json_safe(data)
