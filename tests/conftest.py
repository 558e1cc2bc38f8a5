from __future__ import annotations

from pathlib import Path

import pytest

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
