"""One level's trajectories of a building run, for PedPy.

A building's trajectories.sqlite holds every pedestrian's plan position (x, y) in
JuPedSim's table ``trajectory_data`` and, in ``place_data``, their height and the level or
stair they stand on (:meth:`pedmesh.run.output.RunWriter.trajectory_frame`). Stacked
floors share their plan, so PedPy (which reads x and y only) needs one level at a time:
:func:`level_trajectories` writes a JuPedSim file of one level's rows, with that level's
walkable area as its geometry.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path

from ..errors import PedmeshError

__all__ = ["level_trajectories"]


def level_trajectories(sqlite_path: str | Path, place: str, out: str | Path, *,
                       walkable_wkt: str | None = None) -> Path:
    """Write the rows of level (or stair) ``place`` of a building run's trajectories.sqlite
    to ``out``, a JuPedSim SQLite file (schema version 2) that
    ``pedpy.load_trajectory_from_jupedsim_sqlite`` reads; ``walkable_wkt``: the level's
    walkable area (default: the run's geometry entry). Returns ``out``."""
    src = Path(sqlite_path)
    out = Path(out)
    if not src.is_file():
        raise PedmeshError(f"{src}: no such trajectory file")
    con = sqlite3.connect(src)
    try:
        tables = {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        if "place_data" not in tables:
            raise PedmeshError(f"{src}: not the trajectories of a building (no place_data)")
        places = [r[0] for r in con.execute("SELECT DISTINCT place FROM place_data")]
        if place not in places:
            raise PedmeshError(f"{src}: nobody was ever on '{place}' (places: "
                               f"{', '.join(sorted(places))})")
        out.unlink(missing_ok=True)
        con.execute("ATTACH DATABASE ? AS lvl", (str(out),))
        for table in ("trajectory_data", "metadata", "geometry", "frame_data"):
            sql = con.execute("SELECT sql FROM sqlite_master WHERE name = ?",
                              (table,)).fetchone()[0]
            con.execute(sql.replace(f"CREATE TABLE {table}", f"CREATE TABLE lvl.{table}", 1))
        con.execute("INSERT INTO lvl.trajectory_data SELECT t.* FROM trajectory_data t "
                    "JOIN place_data p ON t.frame = p.frame AND t.id = p.id "
                    "WHERE p.place = ?", (place,))
        con.execute("INSERT INTO lvl.metadata SELECT * FROM metadata")
        con.execute("INSERT INTO lvl.frame_data SELECT * FROM frame_data")
        if walkable_wkt is None:
            con.execute("INSERT INTO lvl.geometry SELECT * FROM geometry")
        else:
            h = con.execute("SELECT hash FROM geometry").fetchone()[0]
            con.execute("INSERT INTO lvl.geometry VALUES (?, ?)", (h, walkable_wkt))
            import shapely

            b = shapely.from_wkt(walkable_wkt).bounds
            for k, v in zip(("xmin", "ymin", "xmax", "ymax"), b):
                con.execute("INSERT OR REPLACE INTO lvl.metadata VALUES (?, ?)", (k, repr(v)))
        con.commit()
        con.execute("DETACH DATABASE lvl")
    finally:
        con.close()
    return out
