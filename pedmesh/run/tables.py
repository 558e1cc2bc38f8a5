"""Reading the CSV tables of a run folder (``evacuation.csv``, ``outflow.csv``,
``outflow_kernel.csv``, ``exits.csv``), the one way every reader does it.

Rows are written whole, each with its newline, and flushed: a last line without its
newline was cut short by a killed run and is left out.

The tables are written with the csv module (:func:`pedmesh.run.output.RunWriter.append_rows`):
a name with a comma, a quote or a newline is quoted, so a name is read back with the csv
module too, never by splitting a line at its commas. A table that cannot be read raises
:class:`BrokenTableError`, one line naming the file, the line and what is wrong with it.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import PedmeshError
from ..io.run_folder import EXITS

__all__ = ["BrokenTableError", "read_number_table", "read_rows", "crossings_from_rows"]


class BrokenTableError(PedmeshError, ValueError):
    """A CSV table of a run folder is missing or cannot be read (the message names it)."""


def read_rows(path: str | Path) -> tuple[list[str], list[list[str]]]:
    """(header, rows) of a CSV table, each a list of its fields as written (quoted names
    unquoted)."""
    path = Path(path)
    try:
        with open(path, encoding="utf-8", newline="") as f:
            rows = list(csv.reader(f))
    except FileNotFoundError:
        raise BrokenTableError(f"{path}: missing") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise BrokenTableError(f"{path}: cannot be read ({exc})") from None
    if not rows:
        raise BrokenTableError(f"{path}: empty (not even its header line)")
    return rows[0], [r for r in rows[1:] if r]


def read_number_table(path: str | Path, columns: int | None = None
                      ) -> tuple[list[str], np.ndarray]:
    """(header, numbers (k, len(header))) of a CSV table whose rows are numbers under a
    header of names; ``columns``: the number of columns the table must have (None: as
    many as its header)."""
    path = Path(path)
    header, rows = read_rows(path)
    if rows and not _ends_with_newline(path):
        rows = rows[:-1]  # (a last line without its newline: cut short by a killed run)
    width = len(header)
    if columns is not None and width != columns:
        raise BrokenTableError(f"{path}: the header has {width} columns, expected {columns} "
                               f"({','.join(header)[:80]!r})")
    data = np.empty((len(rows), width))
    for k, row in enumerate(rows):
        if len(row) != width:
            if k == len(rows) - 1 and len(row) < width:
                data = data[:k]  # the last line cut short by a killed run: dropped
                break
            raise BrokenTableError(f"{path}: line {k + 2} has {len(row)} fields, the header "
                                   f"{width}")
        try:
            data[k] = [float(v) for v in row]
        except ValueError:
            raise BrokenTableError(f"{path}: line {k + 2} is not numbers: "
                                   f"{','.join(row)[:80]!r}") from None
    return header, data


def _ends_with_newline(path: Path) -> bool:
    with open(path, "rb") as f:
        f.seek(0, 2)
        if f.tell() == 0:
            return True
        f.seek(-1, 2)
        return f.read(1) == b"\n"


def crossings_from_rows(rows: Sequence[Sequence[str]], path: str | Path = EXITS):
    """(ids, exit names, times [s]) of the rows ``id, exit, t`` of exits.csv (fields, as
    :func:`read_rows` returns them or a memory run keeps them)."""
    ids, names, times = [], [], []
    for k, r in enumerate(rows):
        if len(r) != 3:
            raise BrokenTableError(f"{path}: line {k + 2} has {len(r)} fields, expected 3 "
                                   "(id, exit, t)")
        try:
            ids.append(int(r[0]))
            times.append(float(r[2]))
        except ValueError:
            raise BrokenTableError(f"{path}: line {k + 2} is not 'id, exit, t'") from None
        names.append(str(r[1]))
    return np.array(ids, np.int64), np.array(names, dtype=object), np.array(times, float)
