"""pedmesh's native room format: one JSON object, coordinates in metres.

Schema (keys not listed are an error)::

    {
      "format": "pedmesh-room",          # optional; if present exactly this
      "version": 1,                      # optional; if present 1
      "name": "example2",                # optional
      "description": "free text",        # optional
      "units": "m",                      # optional; only "m" is accepted
      "preset": "paper",                 # optional: the parameter preset of its runs
      "seed": 7,                         # optional: the particle models' random seed
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

A building (:mod:`pedmesh.geometry.building`) has ``"levels"`` (each a room's keys plus
``"name"`` and ``"z"`` [m]) and ``"stairs"`` instead of the room keys; a file with
``"levels"`` reads as a :class:`~pedmesh.geometry.Building`, one without as a
:class:`~pedmesh.geometry.Room`, unchanged.

Element names are optional (``exit-1``, ``obstacle-2``, ... are used when missing). Saving
writes every float with ``repr`` precision, so ``load_room(save_room(room))`` is exact.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ...errors import GeometryError, RoomFileError
from ..building import Building, Level, Stair
from ..room import (
    Exit,
    MeasurementArea,
    MeasurementLine,
    Obstacle,
    Room,
    StartArea,
)
from ._registry import RoomFormat, read_text, register_format

__all__ = ["room_from_dict", "room_to_dict", "building_from_dict", "building_to_dict",
           "read_native", "write_native", "FORMAT_NAME"]

FORMAT_NAME = "pedmesh-room"
FORMAT_VERSION = 1

_TOP_KEYS = {
    "format", "version", "name", "description", "units", "outline", "obstacles", "exits",
    "start_areas", "measurement_lines", "measurement_areas", "preset", "seed",
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


def room_from_dict(data: Any, source: str = "room") -> Room | Building:
    """Build a :class:`Room` (or, with ``"levels"``, a :class:`Building`) from a
    native-format dict, with strict key checks."""
    if not isinstance(data, dict):
        raise RoomFileError(f"{source}: the top level must be a JSON object, "
                            f"got {type(data).__name__}")
    if "levels" in data:
        return building_from_dict(data, source)
    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        hint = " (a building's levels and stairs go in 'levels' and 'stairs')" \
            if unknown[0] == "stairs" else ""
        raise RoomFileError(
            f"{source}: unknown key '{unknown[0]}' (allowed: {', '.join(sorted(_TOP_KEYS))})"
            + hint
        )
    _check_header(data, source)
    return _room(data, source)


def _check_header(data: dict, source: str) -> None:
    if "format" in data and data["format"] != FORMAT_NAME:
        raise RoomFileError(f"{source}: 'format' must be '{FORMAT_NAME}', got {data['format']!r}")
    if "version" in data and data["version"] != FORMAT_VERSION:
        raise RoomFileError(
            f"{source}: unsupported format version {data['version']!r} (this pedmesh reads 1)"
        )
    if data.get("units", "m") != "m":
        raise RoomFileError(f"{source}: 'units' must be 'm' (metres), got {data['units']!r}")


def _room(data: dict, source: str, exits_elsewhere: tuple[str, ...] = ()) -> Room:
    """The room of a dict whose keys were checked (``exits_elsewhere``: see
    :class:`~pedmesh.geometry.room.Room`)."""
    if "outline" not in data:
        raise RoomFileError(f"{source}: missing required key 'outline' (the room's wall polygon)")
    kwargs: dict[str, Any] = {"outline": data["outline"], "exits_elsewhere": exits_elsewhere}
    for key in ("name", "description", "preset", "seed"):
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


_BUILDING_KEYS = {"format", "version", "name", "description", "units", "preset", "seed",
                  "levels", "stairs"}
_LEVEL_KEYS = (_TOP_KEYS - {"format", "version", "units", "preset", "seed",
                           "description"}) | {"z"}
_STAIR_KEYS = {"name", "polygon", "bottom", "top", "speed_up", "speed_down"}


def _checked_object(item: Any, where: str, what: str, allowed: set[str],
                    required: tuple[str, ...]) -> str:
    """A one-line error unless ``item`` is a JSON object with only ``allowed`` keys and
    every ``required`` one; returns ``where`` (the place for later messages)."""
    if not isinstance(item, dict):
        raise RoomFileError(f"{where}: each {what} must be a JSON object")
    bad = sorted(set(item) - allowed)
    if bad:
        raise RoomFileError(f"{where}: unknown key '{bad[0]}' for a {what} (allowed: "
                            f"{', '.join(sorted(allowed))})")
    for key in required:
        if key not in item:
            raise RoomFileError(f"{where}: a {what} needs '{key}'")
    return where


def _checked_name(name: Any, where: str, what: str) -> str:
    """``name`` if it is a non-empty string, else a one-line error naming ``where`` (the
    level's or stair's place in the file) and the type given."""
    if not isinstance(name, str) or not name.strip():
        raise GeometryError(f"{where}: the {what}'s name must be a non-empty string, got "
                            f"{name!r} ({type(name).__name__})")
    return name


def building_from_dict(data: dict, source: str = "building") -> Building:
    """Build a :class:`Building` from a native-format dict with ``"levels"``."""
    unknown = sorted(set(data) - _BUILDING_KEYS)
    if unknown:
        raise RoomFileError(f"{source}: unknown key '{unknown[0]}' for a building (allowed: "
                            f"{', '.join(sorted(_BUILDING_KEYS))}; a level's rooms go in "
                            "'levels')")
    _check_header(data, source)
    levels_in, stairs_in = data["levels"], data.get("stairs", [])
    for key, items in (("levels", levels_in), ("stairs", stairs_in)):
        if not isinstance(items, list):
            raise RoomFileError(f"{source}: '{key}' must be a list, got {type(items).__name__}")
    levels = []
    # a level's start areas may head for any exit of the building (the Building checks)
    names = [e.get("name") for lv in levels_in if isinstance(lv, dict)
             for e in (lv.get("exits") or []) if isinstance(e, dict)]
    for i, item in enumerate(levels_in):
        where = _checked_object(item, f"{source}: levels[{i}]", "level", _LEVEL_KEYS,
                                ("name", "z"))
        name = _checked_name(item["name"], where, "level")
        own = {e.get("name") for e in (item.get("exits") or []) if isinstance(e, dict)}
        elsewhere = tuple(n for n in names if isinstance(n, str) and n not in own)
        try:
            room = _room({k: v for k, v in item.items() if k != "z"}, f"{where} ('{name}')",
                         elsewhere)
        except GeometryError as exc:  # (the room's own message: say whose room it is)
            raise GeometryError(f"level '{name}': {exc}") from None
        levels.append(Level(name, item["z"], room))
    stairs = []
    for i, item in enumerate(stairs_in):
        where = _checked_object(item, f"{source}: stairs[{i}]", "stair", _STAIR_KEYS,
                                ("polygon", "bottom", "top"))
        if "name" in item:
            _checked_name(item["name"], where, "stair")
        stairs.append(Stair(**{"name": f"stair-{i + 1}", **item}))
    kwargs = {k: data[k] for k in ("name", "description", "preset", "seed") if k in data}
    return Building(levels=levels, stairs=stairs, **kwargs)


def building_to_dict(b: Building) -> dict[str, Any]:
    """The native-format dict of a building (inverse of :func:`building_from_dict`)."""
    out: dict[str, Any] = {"format": FORMAT_NAME, "version": FORMAT_VERSION, "name": b.name}
    if b.description:
        out["description"] = b.description
    if b.preset is not None:
        out["preset"] = b.preset
    if b.seed is not None:
        out["seed"] = b.seed
    out["units"] = "m"
    levels = []
    for lv in b.levels:
        d = {k: v for k, v in room_to_dict(lv.room).items()
             if k not in ("format", "version", "units", "name", "description", "preset",
                          "seed")}
        levels.append({"name": lv.name, "z": lv.z, **d})
    out["levels"] = levels
    out["stairs"] = [{"name": s.name, "polygon": [list(p) for p in s.polygon],
                      "bottom": {"level": s.bottom.level, "edge": [list(p) for p in s.bottom.edge]},
                      "top": {"level": s.top.level, "edge": [list(p) for p in s.top.edge]},
                      "speed_up": s.speed_up, "speed_down": s.speed_down} for s in b.stairs]
    return out


def room_to_dict(room: Room) -> dict[str, Any]:
    """The native-format dict of a room (inverse of :func:`room_from_dict`)."""
    out: dict[str, Any] = {"format": FORMAT_NAME, "version": FORMAT_VERSION, "name": room.name}
    if room.description:
        out["description"] = room.description
    if room.preset is not None:
        out["preset"] = room.preset
    if room.seed is not None:
        out["seed"] = room.seed
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


def read_native(path: str | Path) -> Room | Building:
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


def write_native(room: Room | Building, path: str | Path) -> None:
    """Write ``room`` (or a building) in the native format."""
    from ..site import is_building

    data = building_to_dict(room) if is_building(room) else room_to_dict(room)
    Path(path).write_text(_dumps(data), encoding="utf-8")


register_format(RoomFormat("pedmesh-json", (".json",), read_native, write_native))
