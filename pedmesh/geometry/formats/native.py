"""pedmesh's native room format: one JSON object, coordinates in metres.

Schema (keys not listed are an error)::

    {
      "format": "pedmesh-room",          # optional; if present exactly this
      "version": 1,                      # optional; if present 1
      "name": "example2",                # optional
      "description": "free text",        # optional
      "units": "m",                      # optional; only "m" is accepted
      "preset": "paper",                 # optional: the parameter preset of its runs
      "outline": [[x, y], ...],          # required: outer wall polygon
      "obstacles": [{"name": "pillar", "polygon": [[x, y], ...]}],
      "exits": [{"name": "door", "polyline": [[x, y], [x, y], ...]}],
      "start_areas": [{"name": "block", "polygon": [[x, y], ...],
                       "spacing": 1.0,    # or "count": 100 or "density": 2.0 [ped/m^2]
                       # optional (pedmesh.population): distributions of the premovement
                       # time [s], free speed [m/s], body radius [m]; the exits to take
                       "premovement": {"distribution": "uniform", "min": 0, "max": 60},
                       "speed": 1.34, "radius": 0.2, "exits": ["north"]},
                      # an entrance: people enter here at a rate [1/s] from a start [s]
                      # (or at "times": [...] [s]), instead of standing here at t = 0
                      {"name": "gate", "polygon": [...], "count": 50,
                       "arrivals": {"rate": 1.5, "start": 0}}],
      "measurement_lines": [{"name": "line", "polyline": [[x, y], ...]}],
      "measurement_areas": [{"name": "area", "polygon": [[x, y], ...]}]
    }

Element names are optional (``exit-1``, ``obstacle-2``, ... are used when missing). Saving
writes every float with ``repr`` precision, so ``load_room(save_room(room))`` is exact.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ...errors import GeometryError, RoomFileError
from ..room import (
    Exit,
    MeasurementArea,
    MeasurementLine,
    Obstacle,
    Room,
    StartArea,
)
from ._registry import RoomFormat, read_text, register_format

__all__ = ["room_from_dict", "room_to_dict", "read_native", "write_native", "FORMAT_NAME"]

FORMAT_NAME = "pedmesh-room"
FORMAT_VERSION = 1

_TOP_KEYS = {
    "format", "version", "name", "description", "units", "outline", "obstacles", "exits",
    "start_areas", "measurement_lines", "measurement_areas", "preset",
}
# list key -> (element class, label, coordinate key, optional keys)
_ELEMENTS: dict[str, tuple[type, str, str, tuple[str, ...]]] = {
    "obstacles": (Obstacle, "obstacle", "polygon", ()),
    "exits": (Exit, "exit", "polyline", ()),
    "start_areas": (StartArea, "start area", "polygon", ("count", "spacing", "density",
                                                         "premovement", "speed", "radius",
                                                         "exits", "arrivals")),
    "measurement_lines": (MeasurementLine, "measurement line", "polyline", ()),
    "measurement_areas": (MeasurementArea, "measurement area", "polygon", ()),
}


def room_from_dict(data: Any, source: str = "room") -> Room:
    """Build a :class:`Room` from a native-format dict, with strict key checks."""
    if not isinstance(data, dict):
        raise RoomFileError(f"{source}: the top level must be a JSON object, "
                            f"got {type(data).__name__}")
    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        raise RoomFileError(
            f"{source}: unknown key '{unknown[0]}' (allowed: {', '.join(sorted(_TOP_KEYS))})"
        )
    if "format" in data and data["format"] != FORMAT_NAME:
        raise RoomFileError(f"{source}: 'format' must be '{FORMAT_NAME}', got {data['format']!r}")
    if "version" in data and data["version"] != FORMAT_VERSION:
        raise RoomFileError(
            f"{source}: unsupported format version {data['version']!r} (this pedmesh reads 1)"
        )
    if data.get("units", "m") != "m":
        raise RoomFileError(f"{source}: 'units' must be 'm' (metres), got {data['units']!r}")
    if "outline" not in data:
        raise RoomFileError(f"{source}: missing required key 'outline' (the room's wall polygon)")
    kwargs: dict[str, Any] = {"outline": data["outline"]}
    for key in ("name", "description", "preset"):
        if key in data:
            kwargs[key] = data[key]
    for key, (cls, label, coord_key, optional) in _ELEMENTS.items():
        items = data.get(key, [])
        if not isinstance(items, list):
            raise RoomFileError(f"{source}: '{key}' must be a list, got {type(items).__name__}")
        elements = []
        for i, item in enumerate(items):
            where = f"{source}: {key}[{i}]"
            if not isinstance(item, dict):
                raise RoomFileError(f"{where}: each {label} must be a JSON object")
            allowed = {"name", coord_key, *optional}
            bad = sorted(set(item) - allowed)
            if bad:
                name = item.get("name")
                named = f" ('{name}')" if isinstance(name, str) else ""
                raise RoomFileError(
                    f"{where}{named}: unknown key '{bad[0]}' for a {label} "
                    f"(allowed: {', '.join(sorted(allowed))})"
                )
            if coord_key not in item:
                raise RoomFileError(f"{where}: {label} has no '{coord_key}'")
            args = {k: item[k] for k in allowed if k in item}
            args.setdefault("name", f"{label.replace(' ', '-')}-{i + 1}")
            elements.append(cls(**args))
        kwargs[key] = elements
    return Room(**kwargs)


def room_to_dict(room: Room) -> dict[str, Any]:
    """The native-format dict of a room (inverse of :func:`room_from_dict`)."""
    out: dict[str, Any] = {"format": FORMAT_NAME, "version": FORMAT_VERSION, "name": room.name}
    if room.description:
        out["description"] = room.description
    if room.preset is not None:
        out["preset"] = room.preset
    out["units"] = "m"
    out["outline"] = [list(p) for p in room.outline]
    for key, (cls, label, coord_key, optional) in _ELEMENTS.items():
        items = []
        for el in getattr(room, key):
            d: dict[str, Any] = {"name": el.name,
                                 coord_key: [list(p) for p in getattr(el, coord_key)]}
            for k in optional:
                v = getattr(el, k)
                if v is None:
                    continue
                if hasattr(v, "to_spec"):  # a distribution (pedmesh.population)
                    v = v.to_spec()
                elif k == "exits":
                    v = ([e for e, _ in v] if all(f is None for _, f in v) else dict(v))
                d[k] = v
            items.append(d)
        if items:
            out[key] = items
    return out


def _dumps(data: dict[str, Any]) -> str:
    """JSON with one line per element and coordinates written compactly."""
    lines = ["{"]
    keys = list(data)
    for n, key in enumerate(keys):
        comma = "," if n < len(keys) - 1 else ""
        value = data[key]
        if isinstance(value, list) and value and isinstance(value[0], dict):
            lines.append(f"  {json.dumps(key)}: [")
            for m, el in enumerate(value):
                c2 = "," if m < len(value) - 1 else ""
                lines.append(f"    {json.dumps(el)}{c2}")
            lines.append(f"  ]{comma}")
        else:
            lines.append(f"  {json.dumps(key)}: {json.dumps(value)}{comma}")
    lines.append("}")
    return "\n".join(lines) + "\n"


def read_native(path: str | Path) -> Room:
    """Read a native pedmesh room file."""
    text = read_text(path)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise RoomFileError(
            f"{path}: invalid JSON at line {exc.lineno}, column {exc.colno} ({exc.msg})"
        ) from None
    if isinstance(data, dict) and data.get("type") == "FeatureCollection":
        raise RoomFileError(f"{path}: this is GeoJSON; give the file a .geojson suffix")
    return room_from_dict(data, str(path))


def write_native(room: Room, path: str | Path) -> None:
    """Write ``room`` in the native format."""
    Path(path).write_text(_dumps(room_to_dict(room)), encoding="utf-8")


register_format(RoomFormat("pedmesh-json", (".json",), read_native, write_native))
