from __future__ import annotations

from pathlib import Path

import pytest
from pedmesh.mesh import triangulate

ROOT = Path(__file__).resolve().parents[1]
GEOMETRIES = ROOT / "geometries"
SHIPPED = sorted(p for p in GEOMETRIES.iterdir() if p.suffix in (".json", ".geojson", ".dxf"))


@pytest.fixture(scope="session")
def geometries_dir() -> Path:
    return GEOMETRIES


@pytest.fixture(scope="session")
def load_shipped():
    """Load a shipped geometry by file name (cached per session)."""
    from pedmesh import load_room

    cache: dict[str, object] = {}

    def _load(name: str):
        if name not in cache:
            cache[name] = load_room(GEOMETRIES / name)
        return cache[name]

    return _load


@pytest.fixture
def background_writers(monkeypatch) -> list:
    """A list that gets one entry for each background writer a run makes
    (:class:`pedmesh.run.background.BackgroundWriter`, as the run driver creates it)."""
    from pedmesh.run import background, driver

    made: list = []

    class Counted(background.BackgroundWriter):
        def __init__(self, writer):
            made.append(1)
            super().__init__(writer)

    monkeypatch.setattr(driver, "BackgroundWriter", Counted)
    return made


@pytest.fixture(scope="session")
def mirrored_mesh():
    """Example 2's room as an exactly mirror-symmetric mesh (the upper half meshed, then
    reflected about y = 25). Returns (mesh, mirror, upper, tri_mirror): ``mirror[v]`` is the
    image of vertex ``upper[v]``; ``tri_mirror[t]`` the image of triangle t."""
    import numpy as np

    from pedmesh import Exit, Room, StartArea, TriMesh

    half = Room([(0, 25), (100, 25), (100, 50), (0, 50)],
                exits=[Exit("exit", [(100, 25), (100, 30)])],
                start_areas=[StartArea("block", [(0, 25), (48, 25), (48, 50), (0, 50)],
                                       spacing=1.0)])
    m = triangulate(half, max_area=2.0)
    p = m.points
    n = len(p)
    on_axis = p[:, 1] == 25.0
    twin = np.where(on_axis, np.arange(n), n + np.arange(n))
    pts = np.concatenate([p, p * [1, -1] + [0, 50]])
    tri = np.concatenate([m.triangles, twin[m.triangles]])
    keep = ~np.all(p[m.segments][:, :, 1] == 25.0, axis=1)  # the axis is interior now
    seg = np.concatenate([m.segments[keep], twin[m.segments[keep]]])
    kind = np.concatenate([m.segment_kind[keep]] * 2)
    owner = np.concatenate([m.segment_owner[keep]] * 2)
    used = np.zeros(len(pts), bool)
    used[tri.ravel()] = True
    renum = np.cumsum(used) - 1
    mesh = TriMesh(pts[used], renum[tri], renum[seg], kind, owner, ("exit",))
    mt = m.n_triangles
    tri_mirror = np.concatenate([np.arange(mt) + mt, np.arange(mt)])
    return mesh, renum[twin], renum[np.arange(n)], tri_mirror
