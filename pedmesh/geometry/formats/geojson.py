"""Rooms as GeoJSON: a FeatureCollection whose features carry a ``role`` property.

=================  ============  =======================================================
role               geometry      other properties
=================  ============  =======================================================
room               Polygon       name, description, preset (interior rings become obstacles)
obstacle           Polygon       name
exit               LineString    name
start              Polygon       name and one of count, spacing [m], density [ped/m^2]
measurement_line   LineString    name
measurement_area   Polygon       name
=================  ============  =======================================================

Exactly one ``room`` feature is required. Unknown roles, unknown properties and geometry
types that do not fit the role are errors. Coordinates are metres in a local frame (not
longitude/latitude).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ...errors import RoomFileError
from ..room import Room
from ._registry import RoomFormat, read_text, register_format
from .native import room_from_dict, room_to_dict

__all__ = ["read_geojson", "write_geojson", "room_to_geojson", "room_from_geojson"]

_ROLES = {
    # role: (native list key or None for the room, geometry type, coordinate key, extra props)
    "room": (None, "Polygon", "outline", ("description", "preset")),
    "obstacle": ("obstacles", "Polygon", "polygon", ()),
    "exit": ("exits", "LineString", "polyline", ()),
    "start": ("start_areas", "Polygon", "polygon", ("count", "spacing", "density")),
    "measurement_line": ("measurement_lines", "LineString", "polyline", ()),
    "measurement_area": ("measurement_areas", "Polygon", "polygon", ()),
}


def room_from_geojson(data: Any, source: str = "geojson") -> Room:
    """Build a room from a GeoJSON FeatureCollection dict."""
    if not isinstance(data, dict) or data.get("type") != "FeatureCollection":
        raise RoomFileError(f"{source}: the top level must be a GeoJSON FeatureCollection")
    features = data.get("features")
    if not isinstance(features, list):
        raise RoomFileError(f"{source}: 'features' must be a list")
    native: dict[str, Any] = {}
    for i, feat in enumerate(features):
        where = f"{source}: feature {i}"
        if not isinstance(feat, dict) or feat.get("type") != "Feature":
            raise RoomFileError(f"{where}: not a GeoJSON Feature")
        props = feat.get("properties") or {}
        if not isinstance(props, dict):
            raise RoomFileError(f"{where}: 'properties' must be an object")
        role = props.get("role")
        if role not in _ROLES:
            raise RoomFileError(
                f"{where}: unknown role {role!r} (known roles: {', '.join(_ROLES)})"
            )
        key, gtype, coord_key, extra = _ROLES[role]
        name = props.get("name")
        where = f"{where} ({role}" + (f" '{name}')" if isinstance(name, str) else ")")
        allowed = {"role", "name", *extra}
        bad = sorted(set(props) - allowed)
        if bad:
            raise RoomFileError(
                f"{where}: unknown property '{bad[0]}' (allowed: {', '.join(sorted(allowed))})"
            )
        geom = feat.get("geometry")
        if not isinstance(geom, dict) or geom.get("type") != gtype:
            got = geom.get("type") if isinstance(geom, dict) else geom
            raise RoomFileError(f"{where}: geometry must be a {gtype}, got {got!r}")
        coords = geom.get("coordinates")
        if not isinstance(coords, list) or not coords:
            raise RoomFileError(f"{where}: geometry has no coordinates")
        if gtype == "Polygon":
            exterior, holes = coords[0], coords[1:]
        else:
            exterior, holes = coords, []
        if role == "room":
            if "outline" in native:
                raise RoomFileError(f"{where}: more than one 'room' feature")
            native["outline"] = exterior
            if isinstance(name, str):
                native["name"] = name
            for k in ("description", "preset"):
                if k in props:
                    native[k] = props[k]
            for k, hole in enumerate(holes):
                native.setdefault("obstacles", []).append(
                    {"name": f"hole-{k + 1}", "polygon": hole}
                )
            continue
        if holes:
            raise RoomFileError(f"{where}: a {role} polygon cannot have holes")
        el: dict[str, Any] = {coord_key: exterior}
        if name is not None:
            el["name"] = name
        for k in extra:
            if k in props:
                el[k] = props[k]
        native.setdefault(key, []).append(el)
    if "outline" not in native:
        raise RoomFileError(f"{source}: no feature with role 'room' (the outer walls)")
    return room_from_dict(native, source)


def room_to_geojson(room: Room) -> dict[str, Any]:
    """A GeoJSON FeatureCollection dict of the room."""
    d = room_to_dict(room)

    def feature(role: str, gtype: str, coords: list, props: dict) -> dict:
        ring = coords + [coords[0]] if gtype == "Polygon" else coords
        geometry = {"type": gtype, "coordinates": [ring] if gtype == "Polygon" else ring}
        return {"type": "Feature", "properties": {"role": role, **props}, "geometry": geometry}

    room_props: dict[str, Any] = {"name": room.name}
    if room.description:
        room_props["description"] = room.description
    if room.preset is not None:
        room_props["preset"] = room.preset
    feats = [feature("room", "Polygon", d["outline"], room_props)]
    for role, (key, gtype, coord_key, extra) in _ROLES.items():
        if key is None:
            continue
        for el in d.get(key, []):
            props = {"name": el["name"], **{k: el[k] for k in extra if k in el}}
            feats.append(feature(role, gtype, el[coord_key], props))
    return {"type": "FeatureCollection", "features": feats}


def read_geojson(path: str | Path) -> Room:
    """Read a room from a GeoJSON file."""
    text = read_text(path)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise RoomFileError(
            f"{path}: invalid JSON at line {exc.lineno}, column {exc.colno} ({exc.msg})"
        ) from None
    return room_from_geojson(data, str(path))


def write_geojson(room: Room, path: str | Path) -> None:
    """Write a room as a GeoJSON FeatureCollection."""
    Path(path).write_text(json.dumps(room_to_geojson(room), indent=1) + "\n", encoding="utf-8")


register_format(RoomFormat("geojson", (".geojson",), read_geojson, write_geojson))
