"""Running an ensemble's members on Dask (see :mod:`pedmesh.ensembles`): which members
an earlier call already finished (resume), the submission of the others to a cluster, and
the rows of ``ensemble.csv``, each from its member's own ``summary.json``."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Mapping, Sequence

from .member import clear_member, existing_run, run_member, summary_row
from .plan import EnsembleError, Member
from .stats import write_csv
from ..io import run_folder as F


def resume(plan: list[Member], out: Path) -> tuple[dict[str, dict], list[Member]]:
    """The first rows of ensemble.csv (members already finished in ``out``, with the
    values of their summaries, the others ``pending``) and the members still to run. The
    folders of members that must run again and hold an unfinished run are cleared, once
    every member's folder has been checked."""
    import pandas as pd

    rows: dict[str, dict] = {}
    todo: list[Member] = []
    previous: dict[str, dict] = {}
    try:  # the workers of members an earlier pedmesh did not name in their summaries
        old = pd.read_csv(out / F.ENSEMBLE_CSV, dtype=str, keep_default_na=False)
        if {"member", "worker"} <= set(old.columns):
            previous = {str(r["member"]): r for r in old.to_dict("records")}
    except (ValueError, OSError, pd.errors.ParserError):
        previous = {}
    clear = []
    for m in plan:
        done, stale = existing_run(m)
        base = {"member": m.member, "point": m.point, "seed": m.seed, **m.values}
        if done is None:
            todo.append(m)
            rows[m.member] = {**base, "status": "pending", "error": ""}
            if stale:
                clear.append(m.out_dir)
        else:
            prev = previous.get(m.member, {})
            rows[m.member] = {**base, "worker": prev.get("worker", ""),
                              **summary_row(m.out_dir, done)}
    for d in clear:
        clear_member(d)
    return rows, todo


def rows_from_folders(rows: dict[str, dict], plan: list[Member],
                      members: Sequence[Member] | None = None, *,
                      missing: str | None = None) -> None:
    """Update the rows of ``members`` (default: all of ``plan``) from their folders'
    summaries, so that ensemble.csv says what each member's summary.json says; a member
    without a summary keeps its row, or gets status ``missing`` if that is given and its
    row is still ``submitted`` or ``pending``."""
    for m in plan if members is None else members:
        s = F.good_summary(m.out_dir) if m.out_dir.is_dir() else None
        if s is not None:
            rows[m.member].update(summary_row(m.out_dir, s))
        elif missing and rows[m.member].get("status") in ("submitted", "pending"):
            rows[m.member].update(status=missing)


def rows_frame(rows: Mapping[str, dict], plan: list[Member], columns: list[str]):
    """The current rows of the members in ``plan`` as a DataFrame with ``columns`` (None
    where a row has no value yet)."""
    import pandas as pd

    f = pd.DataFrame([rows[m.member] for m in plan])
    for c in columns:
        if c not in f:
            f[c] = None
    return f[columns]


def compute(todo, rows, plan, model, geometry, t_end, mesh_options, preset, seeded, out,
            frame, *, client, scheduler, workers, quiet, max_cells=None,
            max_people=None) -> None:
    """Submit the members in ``todo`` and record their rows as they finish, each from the
    member's own summary. A collected result is released at once, so that Dask does not
    compute it again when the worker holding it dies. On Ctrl-C the members not collected
    take their rows from their folders (``interrupted`` where there is none), once before
    and once after the cluster is closed."""
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise EnsembleError("ensembles need Dask: pip install 'pedmesh[ensemble]'") from None
    from tqdm import tqdm

    own_client = own_cluster = None
    if client is None:
        if scheduler:
            try:
                client = own_client = Client(scheduler, timeout="20s")
            except (OSError, TimeoutError, ValueError) as exc:
                raise EnsembleError(f"cannot reach the Dask scheduler at {scheduler}: "
                                    f"{exc}") from None
        else:
            n = int(workers or os.cpu_count() or 1)
            own_cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                       host="127.0.0.1", dashboard_address="127.0.0.1:0")
            client = own_client = Client(own_cluster)
    interrupted: KeyboardInterrupt | None = None
    pending: dict = {}
    bar = None
    try:
        if not quiet:
            link = getattr(client, "dashboard_link", None)
            n_workers = len(client.scheduler_info().get("workers", {}))
            print(f"pedmesh: {len(todo)} members on {n_workers} Dask worker(s)"
                  + (f"; dashboard {link}" if link else ""), file=sys.stderr)
        tasks = [{"member": m.member, "point": m.point, "seed": m.seed, "values": m.values,
                  "geometry": str(Path(geometry).resolve()), "model": model,
                  "overrides": m.overrides, "t_end": t_end, "out_dir": str(m.out_dir.resolve()),
                  "mesh_options": mesh_options, "preset": preset, "max_cells": max_cells,
                  "max_people": max_people,
                  "model_options": {"seed": m.seed} if seeded else {}} for m in todo]
        for m, t in zip(todo, tasks):
            fut = client.submit(run_member, t, key=f"pedmesh-{m.member}-{time.time_ns()}",
                                pure=False)
            pending[fut] = m
            rows[m.member]["status"] = "submitted"
        bar = tqdm(total=len(pending), unit="run", disable=quiet, file=sys.stderr,
                   desc="ensemble", dynamic_ncols=True)
        for fut in as_completed(list(pending)):
            m = pending.pop(fut)
            try:
                row = fut.result()
            except Exception as exc:  # the worker died under it (too often)
                row = {"status": "failed", "error": f"{type(exc).__name__}: {exc}"}
            fut.release()
            rows[m.member].update({k: v for k, v in row.items() if k != "member"})
            rows_from_folders(rows, plan, [m])
            write_csv(out / F.ENSEMBLE_CSV, frame())
            bar.update(1)
            failed = sum(r.get("status") == "failed" for r in rows.values())
            if failed:
                bar.set_postfix_str(f"{failed} failed", refresh=False)
    except KeyboardInterrupt as exc:
        interrupted = exc
        if pending:
            client.cancel(list(pending))
        rows_from_folders(rows, plan, todo, missing="interrupted")
        write_csv(out / F.ENSEMBLE_CSV, frame())
    finally:
        if bar is not None:
            bar.close()
        if own_client is not None:
            own_client.close()
        if own_cluster is not None:
            own_cluster.close()
    if interrupted is not None:  # members that ended while the cluster shut down
        rows_from_folders(rows, plan, todo, missing="interrupted")
        write_csv(out / F.ENSEMBLE_CSV, frame())
        raise interrupted
