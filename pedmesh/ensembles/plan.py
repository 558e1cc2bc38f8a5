"""An ensemble's plan, made on the client before any cluster starts or anything is
written: the members' seeds, the sweep's grid of points and the members at each, the
checks of the options, parameter names, scheduler address and room, and the claim of the
ensemble's folder."""

from __future__ import annotations

import itertools
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..errors import ParameterError, PedmeshError
from ..mesh.site import check_mesh_size
from ..io import run_folder as F

#: columns of ensemble.csv before the swept parameters' columns are inserted after "seed"
COLUMNS = ["member", "point", "seed", "status", "n_initial", "n_evacuated", "t_evac_50",
           "t_evac_90", "t_evac_100", "wall_time_s", "worker", "error"]
#: the evacuation times [s] of a member's row, summarised per sweep point
TIMES = ("t_evac_50", "t_evac_90", "t_evac_100")


class EnsembleError(PedmeshError):
    """An ensemble cannot start (bad options, or member folders made with other settings)."""


def member_seeds(seed: int, members: int) -> list[int]:
    """The seeds of ``members`` members drawn from the ensemble seed ``seed``: independent
    streams (numpy's SeedSequence spawning), the same for the same ``seed``."""
    children = np.random.SeedSequence(int(seed)).spawn(int(members))
    return [int(c.generate_state(1, np.uint32)[0]) for c in children]


def parse_sweep(items: Sequence[str]) -> dict[str, list[Any]]:
    """``["width=0.8,1.2", "dt=0.01"]`` -> ``{"width": [0.8, 1.2], "dt": [0.01]}`` (values
    parsed as ``--param`` values are; a declared parameter's within its physical range)."""
    from ..parameters import PARAMETERS, parse_overrides

    out: dict[str, list[Any]] = {}
    for item in items:
        if "=" not in item:
            raise ParameterError(f"--sweep expects NAME=V1,V2,..., got '{item}'")
        name, values = item.split("=", 1)
        name = name.strip()
        vals = [v.strip() for v in values.split(",")]
        if not name or not any(vals):
            raise ParameterError(f"--sweep expects NAME=V1,V2,..., got '{item}'")
        if not all(vals):  # (an empty value is a typo: refused, not dropped)
            raise ParameterError(f"--sweep {name}: value {vals.index('') + 1} of {len(vals)} "
                                 f"is empty in '{item}'")
        if name in out:
            raise ParameterError(f"parameter '{name}' is swept twice")
        out[name] = [parse_overrides([f"{name}={v}"])[name] for v in vals]
        if name in PARAMETERS:  # (refused here, not in every member on the cluster)
            for v in out[name]:
                PARAMETERS[name].check(v)
    return out


@dataclass
class Member:
    """A member of the plan: its id (``<point>-<member>``), sweep point, seed, swept
    values, folder, parameter overrides and the settings its run records."""
    member: str
    point: int
    seed: int
    values: dict
    out_dir: Path
    overrides: dict
    settings: dict = field(default_factory=dict)


def plan_members(geometry: str, model: str, members: int, out: Path, *, overrides: dict,
                 sweep: dict[str, list], seed: int, t_end: float, mesh_options: dict,
                 preset: str | None, seeded: bool) -> list[Member]:
    """The members of the ensemble: ``members`` of them (seeds from ``seed``) at every
    point of the grid of ``sweep``, in ``out/members/``, with the settings of their runs
    (``seeded``: the model takes the member's seed)."""
    from ..run.driver import run_settings

    keys = list(sweep)
    points = list(itertools.product(*(sweep[k] for k in keys))) if keys else [()]
    seeds = member_seeds(seed, members)
    plan = []
    for p, values in enumerate(points):
        vals = dict(zip(keys, values))
        for i in range(members):
            mid = f"{p:03d}-{i:04d}"
            ov = {**overrides, **vals}
            opts = {"seed": seeds[i]} if seeded else {}
            m = Member(mid, p, seeds[i], vals, out / F.ENSEMBLE_MEMBERS / mid, ov)
            m.settings = run_settings(model, overrides=ov, t_end=t_end, geometry=geometry,
                                      mesh_options=mesh_options, model_options=opts,
                                      preset=preset)
            plan.append(m)
    return plan


def check_options(entry, members, seed, workers, t_end) -> None:
    """EnsembleError unless ``members`` is a positive integer, ``seed`` a non-negative one,
    ``workers`` None or a positive integer, ``t_end`` a positive number of seconds, and
    ``members`` 1 for a model (registry ``entry``) without random input."""
    if isinstance(members, bool) or not isinstance(members, (int, np.integer)) or members < 1:
        raise EnsembleError(f"members must be a positive integer, got {members!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise EnsembleError(f"seed must be a non-negative integer, got {seed!r}")
    if workers is not None and (not isinstance(workers, (int, np.integer)) or workers < 1):
        raise EnsembleError(f"workers must be a positive integer, got {workers!r}")
    if not (math.isfinite(t_end) and t_end > 0):
        raise EnsembleError(f"t_end must be a positive number of seconds, got {t_end!r}")
    if not entry.random and members > 1:
        raise EnsembleError(f"model '{entry.name}' has no random input: its members would all "
                            "be the same; use members=1 (with a sweep)")


def checked_sweep(sweep: Mapping[str, Sequence[Any]] | None,
                  overrides: Mapping[str, Any] | None) -> tuple[dict[str, list], dict]:
    """The sweep and the fixed overrides as plain dicts; EnsembleError if a swept parameter
    has no values or is also set."""
    if sweep is not None and not isinstance(sweep, Mapping):
        raise EnsembleError(f"sweep must map parameter names to lists of values, e.g. "
                            f"{{'U_f': [1.2, 1.34]}}; got {type(sweep).__name__} {sweep!r:.40}")
    if overrides is not None and not isinstance(overrides, Mapping):
        raise EnsembleError(f"overrides must map parameter names to values, got "
                            f"{type(overrides).__name__} {overrides!r:.40}")
    for k, v in (sweep or {}).items():
        if isinstance(v, (str, bytes)) or not isinstance(v, (Sequence, np.ndarray)):
            raise EnsembleError(f"sweep of '{k}' must be a list of values, got {v!r:.40}")
    sweep = {k: list(v) for k, v in (sweep or {}).items()}
    for k, v in sweep.items():
        if not v:
            raise EnsembleError(f"sweep of '{k}' has no values")
    overrides = dict(overrides or {})
    both = sorted(set(overrides) & set(sweep))
    if both:
        raise EnsembleError(f"parameter '{both[0]}' is both set and swept")
    return sweep, overrides


def check_names(entry, overrides: Mapping[str, Any], sweep: Mapping[str, Any]) -> None:
    """EnsembleError naming the first set or swept parameter that model ``entry`` does not
    declare (checked here, before any cluster starts, not in every member)."""
    known = entry.parameter_names
    for what, names in (("swept", sweep), ("set", overrides)):
        unknown = sorted(set(names) - known)
        if unknown:
            raise EnsembleError(f"unknown parameter '{unknown[0]}' ({what}) for model "
                                f"'{entry.name}' (known: {', '.join(sorted(known))})")


def check_scheduler(scheduler: str | None) -> None:
    """EnsembleError unless ``scheduler`` is None or a Dask address with a host and a port
    (``tcp://HOST:PORT``); checked before anything is written or started."""
    if scheduler is None:
        return
    what = f"scheduler address '{scheduler}'"
    if not isinstance(scheduler, str) or not scheduler.strip():
        raise EnsembleError(f"{what} is empty; give tcp://HOST:PORT")
    try:
        from distributed.comm.addressing import get_address_host_port, parse_address
    except ImportError:
        return  # reported with the install hint when the cluster is needed
    try:
        parse_address(scheduler)
        host, port = get_address_host_port(scheduler)
    except (ValueError, TypeError) as exc:
        raise EnsembleError(f"{what} is not valid ({exc}); give tcp://HOST:PORT") from None
    if not host or not 0 < int(port) < 65536:
        raise EnsembleError(f"{what} is not valid (a host and a port 1-65535 are needed); "
                            "give tcp://HOST:PORT")
    if scheduler.startswith("tcp://") or "://" not in scheduler:
        _probe_scheduler(scheduler, host, int(port))


def _probe_scheduler(scheduler: str, host: str, port: int, timeout: float = 5.0) -> None:
    """EnsembleError at once if nothing listens at ``host:port`` (Dask's own client would
    retry a refused connection until its timeout and then report only that)."""
    import socket

    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except ConnectionRefusedError:
        raise EnsembleError(f"cannot reach the Dask scheduler at {scheduler}: the connection "
                            "was refused (no scheduler listens there; start one with "
                            "'dask scheduler', or leave out --scheduler to use this "
                            "machine)") from None
    except socket.timeout:
        raise EnsembleError(f"cannot reach the Dask scheduler at {scheduler}: no answer "
                            f"within {timeout:g} s (a firewall, or the wrong host)") from None
    except OSError as exc:
        raise EnsembleError(f"cannot reach the Dask scheduler at {scheduler}: "
                            f"{exc.strerror or exc}") from None


def check_room(geometry: str, preset: str | None, mesh_options: Mapping[str, Any],
               max_cells: float | None, max_people: int | None = None) -> str | None:
    """Load the room once on the client, so that a bad room file or an oversized mesh fails
    here and not in every member, and return the preset in use (``preset``, else the room
    file's, else the default)."""
    from ..io import load_room
    from ..presets import resolve_preset
    from ..run.driver import check_crowd

    room = load_room(geometry)
    check_crowd(room, max_people)  # (the crowd limit, --max-people)
    preset = resolve_preset(preset, room)
    check_mesh_size(room, dict(mesh_options), max_cells)
    return preset


def _is_ensemble_dir(d: Path) -> bool:
    """Whether ``d`` holds a pedmesh ensemble: its ensemble.csv (pedmesh's columns) or
    ensemble.json, or nothing but a ``members`` folder."""
    try:
        with open(d / F.ENSEMBLE_CSV, encoding="utf-8") as f:
            if f.readline().startswith(",".join(COLUMNS[:3]) + ","):
                return True
    except (OSError, ValueError):
        pass
    try:
        data = json.loads((d / F.ENSEMBLE_JSON).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        data = None
    if isinstance(data, dict) and ("pedmesh_version" in data
                                   or {"model", "members", "points"} <= set(data)):
        return True
    names = {e.name for e in d.iterdir()} - {F.LOCK}
    return names == {F.ENSEMBLE_MEMBERS} and (d / F.ENSEMBLE_MEMBERS).is_dir()


def claim_ensemble_dir(out: Path):
    """Make ``out`` this ensemble's (as :func:`pedmesh.run.output.claim_run_dir` does for a
    run): refuse a non-empty folder that is not a pedmesh ensemble, before writing
    anything, and one another ensemble is writing into; returns the held lock file."""
    if os.path.lexists(out) and not out.is_dir():
        raise EnsembleError(f"{out}: exists and is not a directory; choose another --out")
    if out.is_dir() and any(e.name != F.LOCK for e in out.iterdir()) \
            and not _is_ensemble_dir(out):
        raise EnsembleError(f"{out}: not empty and not a pedmesh ensemble directory; choose "
                            "another --out (pedmesh does not write into other files)")
    out.mkdir(parents=True, exist_ok=True)
    lock = F.take_lock(out)
    if lock is None:
        raise EnsembleError(f"{out}: another pedmesh ensemble is writing into this "
                            "directory; wait for it or choose another --out")
    return lock
