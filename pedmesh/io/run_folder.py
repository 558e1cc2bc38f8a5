"""The run folder's contract, in one place: the names of its files and what each holds, the
writer protocol every run output follows, and reading a folder's summary and status.

A run folder is written by one of two writers with the same methods
(:class:`WriterProtocol`): :class:`~pedmesh.run.output.RunWriter` (files) and
:class:`~pedmesh.run.memory.MemoryWriter` (arrays, the Python API without ``out_dir``);
:class:`~pedmesh.run.background.BackgroundWriter` makes a RunWriter's queued writes on a
thread of its own. Each method is declared in :data:`WRITER_METHODS` as ``"queued"`` (it
only writes, returns nothing, and may run later on the writer thread, in order with the
other queued writes) or ``"immediate"`` (it runs at once, on the caller's thread); a method
declared nowhere is refused by the background writer rather than run out of order.

Everything that reads a run's output goes through :class:`pedmesh.run.results.RunResult`
(the same type in memory and on disk), which reads the files named here, and through
:func:`read_summary` / :func:`run_status`. No other module spells a file name of the run
folder (a test greps for them).

The names of an ensemble's folder (``pedmesh ensemble``) and of a comparison's folder
(``pedmesh compare``) are here too.
"""

from __future__ import annotations

import json
import math
import numbers
import os
import re
from pathlib import Path
from typing import Any, Mapping, Protocol, Sequence

import numpy as np

from ..errors import PedmeshError
from .files import write_through_part

try:  # POSIX advisory locks; elsewhere the process id in summary.json is checked
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    fcntl = None

# ---------------------------------------------------------------------------- file names
SUMMARY = "summary.json"
EVACUATION = "evacuation.csv"
OUTFLOW = "outflow.csv"
#: (the social force model) the exits' outflow measured by the kernel density
OUTFLOW_KERNEL = "outflow_kernel.csv"
EXITS = "exits.csv"
DENSITY_PVD = "density.pvd"
#: the folder of the density frames (``density_000012.vtu``)
DENSITY_DIR = "density"
PEDESTRIANS_PVD = "pedestrians.pvd"
#: the folder of the pedestrian frames (``pedestrians_000012.vtp``)
PEDESTRIANS_DIR = "pedestrians"
TRAJECTORIES_TXT = "trajectories.txt"
TRAJECTORIES_SQLITE = "trajectories.sqlite"
SAFETY_VTU = "safety.vtu"
LOCK = ".lock"

#: an ensemble's folder: one row per member, the statistics, the members' run folders
ENSEMBLE_CSV = "ensemble.csv"
ENSEMBLE_JSON = "ensemble.json"
ENSEMBLE_MEMBERS = "members"
#: a comparison's folder (``pedmesh compare``): its tables and plots
COMPARISON_CSV = "comparison.csv"
COMPARISON_MD = "comparison.md"
COMPARISON_STAIRS = "stairs.csv"
COMPARISON_PLOTS = {"evacuation": "evacuation.png", "outflow": "outflow.png",
                    "fundamental": "fundamental.png", "density": "density.png"}
#: every file a comparison writes into its folder (beside one run folder per model)
COMPARISON_FILES = (COMPARISON_CSV, COMPARISON_MD, COMPARISON_STAIRS,
                    *COMPARISON_PLOTS.values())
#: the report a folder's ``pedmesh report`` writes by default
REPORT_HTML = "report.html"

#: the files of a run folder and what each holds (``pedmesh run --help`` and the docs print
#: this list); "(particle models)" marks those only particle models write
OUTPUT_FILES: dict[str, str] = {
    SUMMARY: "model, status, n_initial, n_evacuated, t_evac_50/90/100 [s], steps, "
             "dt, wall time, every parameter used with its unit, the run's "
             "settings (room file hash, model, preset, overrides, t_end, mesh), and "
             "the crowd-safety measures (\"safety\", see docs/safety.md)",
    EVACUATION: "t,evacuated (cumulative number out), every sample_interval (0.1 s)",
    OUTFLOW: "t and the flow [ped/s] through each exit, the mean since the previous "
             "row (crossings, or the integrated boundary flux of a continuum model)",
    OUTFLOW_KERNEL: "(particle models) t and the flow [ped/s] through each exit measured "
                    "by the kernel density, as a continuum model measures it",
    DENSITY_PVD: "density on the mesh [ped/m^2] (and velocity [m/s]), one frame per "
                 "output_interval (the frames in density/)",
    PEDESTRIANS_PVD: "(particle models) positions with velocity, speed, local density "
                     "(the frames in pedestrians/)",
    TRAJECTORIES_TXT: "(particle models) id frame x y [m] at the trajectory rate, for "
                      "PedPy's load_trajectory_from_txt; a leaver's last row is on the exit",
    TRAJECTORIES_SQLITE: "(particle models) the same in JuPedSim's SQLite format (with the "
                         "walkable area), for pedpy.load_trajectory_from_jupedsim_sqlite",
    EXITS: "(particle models) id,exit,t of everyone who left",
    SAFETY_VTU: "the crowd-safety maps per cell: peak density on 1 m^2 [ped/m^2] and its "
                "time, worst Fruin level of service (0-5 for A-F, walkway and queuing), "
                "time above 2, 4, 6 /m^2 [s], the social force model's max crowd "
                "pressure [1/s^2]; the numbers are in summary.json under \"safety\"",
}

#: pedmesh's own temporary files in a run folder (exact names); the frames' temporary
#: files (``density_000012.part.vtu``) are inside ``density/`` and ``pedestrians/``
TEMP_FILES = (SUMMARY + ".part", DENSITY_PVD + ".part", PEDESTRIANS_PVD + ".part",
              SAFETY_VTU + ".part", TRAJECTORIES_SQLITE + "-journal")
#: the exact names of everything a run writes into its directory: a rerun removes these
#: and nothing else
RUN_FILES = (*OUTPUT_FILES, DENSITY_DIR, PEDESTRIANS_DIR, LOCK, *TEMP_FILES)
#: a frame's temporary file in density/ or pedestrians/ (see pedmesh.io.vtk)
FRAME_TEMP = re.compile(rf"({DENSITY_DIR}|{PEDESTRIANS_DIR})_\d{{6,}}\.part\.(vtu|vtp)")
#: a frame of density/ or pedestrians/, or its temporary file
FRAME_FILE = re.compile(rf"({DENSITY_DIR}|{PEDESTRIANS_DIR})_\d{{6,}}(\.part)?\.(vtu|vtp)")
#: every status a summary can have
STATUSES = ("running", "finished", "stopped at t_end", "interrupted", "failed")
#: the statuses of a run that ran to its end (everyone out, or t_end reached)
FINISHED_STATUSES = ("finished", "stopped at t_end")


def is_run_file(name: str) -> bool:
    """Whether ``name`` (an entry of a run folder) is one pedmesh writes there."""
    return name in RUN_FILES


# ---------------------------------------------------------------------------- writers
#: every method of the writer protocol: "queued" methods only write (they return nothing
#: and may run later, on the background writer's thread, in order); "immediate" ones run at
#: once on the caller's thread
WRITER_METHODS: dict[str, str] = {
    "start": "immediate", "finish": "immediate",
    "call": "queued", "sample": "queued", "outflow": "queued", "append_rows": "queued",
    "density_frame": "queued", "pedestrian_frame": "queued", "trajectory_frame": "queued",
}
#: the queued writes (:data:`WRITER_METHODS`)
QUEUED_WRITES = frozenset(k for k, v in WRITER_METHODS.items() if v == "queued")


class WriterProtocol(Protocol):
    """What a model and the run driver call on a run's writer (:data:`WRITER_METHODS`).
    ``exit_names``: the exits' names, the columns of outflow.csv; ``header``: the summary's
    fields known before the run."""

    exit_names: list[str]
    header: dict[str, Any]

    def start(self, header: Mapping[str, Any] | None = None) -> None: ...

    def call(self, fn, *args: Any, **kwargs: Any) -> None: ...

    def sample(self, t: float, evacuated: float) -> None: ...

    def outflow(self, t: float, flows: Sequence[float]) -> None: ...

    def append_rows(self, name: str, header: Sequence[str] | str,
                    rows: Sequence[Sequence[Any] | str]) -> None: ...

    def density_frame(self, t: float, mesh, point_data=None, cell_data=None) -> None: ...

    def pedestrian_frame(self, t: float, points: np.ndarray,
                         data: Mapping[str, np.ndarray]) -> None: ...

    def trajectory_frame(self, frame: int, ids: np.ndarray, points: np.ndarray,
                         frame_rate: float, description: str, *,
                         orientation: np.ndarray | None = None,
                         walkable_wkt: str | None = None, z: np.ndarray | None = None,
                         place: Sequence[str] | None = None) -> None: ...

    def finish(self, **summary: Any) -> dict[str, Any]: ...


def undeclared_methods(writer_type: type) -> list[str]:
    """The public methods of a writer class that the protocol does not declare (none for a
    conforming writer) and the declared ones it lacks, as ``"+name"`` / ``"-name"``."""
    public = {n for n in dir(writer_type) if not n.startswith("_")
              and callable(getattr(writer_type, n))}
    helpers = set().union(*(WRITER_HELPERS.get(c.__name__, set())
                            for c in writer_type.__mro__))
    extra = sorted(public - set(WRITER_METHODS) - helpers)
    missing = sorted(set(WRITER_METHODS) - public)
    return [f"+{n}" for n in extra] + [f"-{n}" for n in missing]


#: public methods a writer may have beside the protocol, by class name: none of them is
#: called by a model or the driver through the writer protocol
WRITER_HELPERS: dict[str, set[str]] = {
    "RunWriter": {"close_files"},
    "MemoryWriter": {"result"},
}


# ---------------------------------------------------------------------------- the summary
class RunFolderError(PedmeshError):
    """The output directory cannot be used for this run (not a run, or in use)."""


class BrokenSummaryError(RunFolderError):
    """A run folder's summary.json cannot be read as a pedmesh summary (truncated, not a
    JSON object, wrong-typed fields); the message names the file."""


_NUMBER = "a number"
#: the fields pedmesh reads from a summary and what each must be (None is allowed for
#: every field but the first three, which must be there)
SUMMARY_FIELDS: dict[str, str] = {
    "pedmesh_version": "text", "model": "text", "status": "text",
    "settings": "an object", "mesh": "an object", "parameters": "an object",
    "exits": "an object", "units": "an object", "error": "text", "pid": "a whole number",
    "t_end": _NUMBER, "t_stop": _NUMBER, "n_initial": _NUMBER, "n_evacuated": _NUMBER,
    "t_evac_50": _NUMBER, "t_evac_90": _NUMBER, "t_evac_100": _NUMBER, "steps": _NUMBER,
    "frames": _NUMBER, "wall_time_s": _NUMBER, "dt": _NUMBER,
    "geometry": "text", "room": "text", "warnings": "a list", "safety": "an object",
    "stairs": "an object",
}
#: the fields of the summary's objects that pedmesh reads, and what each must be
NESTED_FIELDS: dict[str, dict[str, str]] = {
    "settings": {"overrides": "an object", "mesh_options": "an object",
                 "model_options": "an object", "preset": "text", "room_sha256": "text"},
    "safety": {"peak_density": "an object", "area_time_above": "an object",
               "time_above": "an object", "level_of_service": "an object",
               "crowd_pressure": "an object", "exits": "an object",
               "clear_times": "an object", "levels": "an object", "error": "text"},
}
_REQUIRED = ("pedmesh_version", "model", "status")


def _is_kind(value: Any, kind: str) -> bool:
    if kind == "text":
        return isinstance(value, str)
    if kind == "an object":
        return isinstance(value, dict)
    if kind == "a list":
        return isinstance(value, list)
    if isinstance(value, bool):
        return False
    if kind == "a whole number":
        return isinstance(value, int)
    return isinstance(value, numbers.Real)


def _json_kind(value: Any) -> str:
    return {dict: "an object", list: "a list", str: "text", bool: "true/false",
            type(None): "null"}.get(type(value), "a number")


def summary_problem(data: Any) -> str | None:
    """What is wrong with ``data`` as a pedmesh summary (None if nothing)."""
    if not isinstance(data, dict):
        kind = {list: "list", str: "string", bool: "true/false", type(None): "null"}.get(
            type(data), "number")
        return f"a JSON {kind}, not an object"
    for key in _REQUIRED:
        if key not in data:
            return f"no '{key}'"
    for key, kind in SUMMARY_FIELDS.items():
        value = data.get(key)
        if value is None and key not in _REQUIRED:
            continue
        if not _is_kind(value, kind):
            return f"'{key}' is {_json_kind(value)}, not {kind}"
    for key, fields in NESTED_FIELDS.items():
        inner = data.get(key)
        for sub, kind in fields.items() if isinstance(inner, dict) else ():
            value = inner.get(sub)
            if value is not None and not _is_kind(value, kind):
                return f"'{key}'.'{sub}' is {_json_kind(value)}, not {kind}"
    if isinstance(data.get("warnings"), list) and not all(
            isinstance(w, str) for w in data["warnings"]):
        return "'warnings' holds something that is not text"
    if data["status"] not in STATUSES:
        return f"unknown status {data['status']!r}"
    return None


def read_summary(d: str | Path) -> tuple[dict | None, str | None]:
    """(summary, None) for a run folder with a good ``summary.json``, (None, what is wrong)
    for a broken one, (None, None) where there is none."""
    path = Path(d) / SUMMARY
    if not path.exists():
        return None, None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        return None, "not UTF-8 text"
    except json.JSONDecodeError as exc:
        return None, f"not valid JSON, truncated? {exc.msg}: line {exc.lineno} " \
                     f"column {exc.colno}"
    except OSError as exc:
        return None, f"cannot be read: {exc.strerror or exc}"
    problem = summary_problem(data)
    return (None, problem) if problem else (data, None)


def good_summary(d: str | Path) -> dict | None:
    """The summary of the run in ``d``, None if there is none or it is broken."""
    return read_summary(d)[0]


def load_summary(d: str | Path) -> dict:
    """The summary of the run in ``d``; :class:`BrokenSummaryError` naming the file if it
    is broken, :class:`RunFolderError` if there is none."""
    data, problem = read_summary(d)
    if problem is not None:
        raise BrokenSummaryError(f"{Path(d) / SUMMARY}: not a pedmesh run summary "
                                 f"({problem})")
    if data is None:
        raise RunFolderError(f"{d}: not a run directory (no {SUMMARY})")
    return data


def has_summary(d: str | Path) -> bool:
    """Whether the folder ``d`` holds a summary.json (good or broken)."""
    return (Path(d) / SUMMARY).is_file()


# ---------------------------------------------------------------------------- locks
def lock_is_held(d: str | Path) -> bool | None:
    """Whether another process holds the folder's lock (None where locks are unknown)."""
    d = Path(d)
    if fcntl is None or not (d / LOCK).exists():
        return None
    with open(d / LOCK, "a+") as f:
        try:
            fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return True
        fcntl.flock(f.fileno(), fcntl.LOCK_UN)
        return False


def take_lock(d: str | Path):
    """Open the folder's lock file and take its lock; returns the open file (keep it open
    while writing), or None if another process holds it."""
    lock = open(Path(d) / LOCK, "a+")
    if fcntl is not None:
        try:
            fcntl.flock(lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            lock.close()
            return None
    return lock


def locks_known() -> bool:
    """Whether this system has advisory locks (else a run's process id is checked)."""
    return fcntl is not None


def pid_alive(pid: Any) -> bool:
    """Whether the process ``pid`` exists."""
    try:
        os.kill(int(pid), 0)
    except (OSError, TypeError, ValueError, OverflowError):
        return False
    return True


def run_status(path: str | Path, summary: Mapping[str, Any] | None = None) -> str | None:
    """The status of the run in ``path``: as recorded, except that a ``running`` run whose
    process is gone (its lock free, or its process id dead) reads as ``interrupted``.
    ``None`` if ``path`` holds no run."""
    d = Path(path)
    s = good_summary(d) if summary is None else summary
    if s is None:
        return None
    status = s.get("status")
    if status == "running":
        held = lock_is_held(d)
        if held is False or (held is None and not pid_alive(s.get("pid"))):
            return "interrupted"
    return status


# ---------------------------------------------------------------------------- writing
def remove_frames(sub: Path) -> None:
    """Remove the frames an earlier run wrote into its folder ``density/`` or
    ``pedestrians/`` (named ``density_000012.vtu``, ``pedestrians_000012.vtp`` and their
    ``.part`` forms), and the folder if nothing else is in it: a file of the user's there
    stays."""
    for e in sub.iterdir():
        if FRAME_FILE.fullmatch(e.name) and e.name.startswith(sub.name + "_") \
                and (e.is_file() or e.is_symlink()):
            e.unlink()
    try:
        sub.rmdir()
    except OSError:  # not empty: the user's files stay, and so does the folder
        pass


def atomic_write(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through ``path.part``: the file is the old one or the new
    one, never half of it (the ``.part`` is removed if the write fails)."""
    write_through_part(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def json_safe(obj: Any) -> Any:
    """JSON-safe copy: numpy scalars to Python, NaN/inf to None."""
    if isinstance(obj, Mapping):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return json_safe(obj.tolist())
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        f = float(obj)
        return f if math.isfinite(f) else None
    return obj
