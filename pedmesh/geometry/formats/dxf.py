"""Rooms from DXF drawings (via ezdxf), by layer name.

Each entity's layer gives its role: ``room``, ``obstacle``, ``exit``, ``start``,
``measurement_line`` or ``measurement_area`` (case-insensitive), optionally followed by
``-NAME`` or ``_NAME`` to name the element (``obstacle-pillar1``, ``EXIT_north``).
Entities on other layers are ignored. Lines, polylines (with arcs), circles, arcs, ellipses
and splines are accepted; curves are flattened to within 1 cm. Polygons (room, obstacle,
start, measurement area) must be closed. A start area takes its parameters from a TEXT or
MTEXT entity on its layer reading ``count=N``, ``spacing=S`` (m) or ``density=D``
(ped/m^2); without one it uses ``spacing=1``. Text on the room layer is the room's
description, and a room layer ``room-NAME`` names the room (else the file name does).
Units are assumed to be metres.

A **building** (:mod:`pedmesh.geometry.building`) puts each level's layers under the level's
name and a dot: ``ground.room``, ``ground.exit-front``, ``first.start-offices``; a TEXT
``z=3.5`` on a level's room layer gives its height [m]. A stair is a closed polyline on a
layer ``stair-NAME``, its two edges LINEs (or 2-point polylines) on
``stair-NAME.bottom-LEVEL`` and ``stair-NAME.top-LEVEL``, and optional TEXT
``speed_up=F`` / ``speed_down=F`` on the stair's layer. A drawing with a dotted room
layer is read as a building.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

from ...errors import RoomFileError
from ..building import Building
from ..room import Room
from ._registry import RoomFormat, existing_file, register_format
from .native import building_to_dict, room_from_dict, room_to_dict

__all__ = ["read_dxf", "write_dxf", "FLATTEN_DISTANCE"]

#: Largest distance [m] between a DXF curve and its polygonal approximation.
FLATTEN_DISTANCE = 0.01

# role -> (native list key or None for the room, closed?)
_ROLES = {
    "measurement_line": ("measurement_lines", False),
    "measurement_area": ("measurement_areas", True),
    "obstacle": ("obstacles", True),
    "start": ("start_areas", True),
    "exit": ("exits", False),
    "room": (None, True),
}
# a TEXT "key=value": the start parameters (count, spacing, density), a level's height z,
# a stair's speed_up/speed_down; the value is read by _number
_KEY_VALUE = re.compile(r"^\s*([A-Za-z_]+)\s*=\s*(.*?)\s*$")
_START_KEYS = ("count", "spacing", "density")
_LEVEL_KEYS = ("z",)
_STAIR_KEYS = ("speed_up", "speed_down")
_STAIR_END = re.compile(r"^stair[-_](.+)\.(bottom|top)[-_](.+)$", re.IGNORECASE)
_STAIR = re.compile(r"^stair[-_](.+)$", re.IGNORECASE)


def _role(layer: str) -> tuple[str, str | None] | None:
    low = layer.lower().replace("-", "_")
    for role in _ROLES:  # longest roles first, so measurement_* wins over other prefixes
        if low == role:
            return role, None
        if low.startswith(role + "_") and len(layer) > len(role) + 1:
            return role, layer[len(role) + 1 :]
    return None


def _key_value(text: str, keys: tuple[str, ...]) -> tuple[str, str] | None:
    """(key, value text) of a TEXT ``key=value`` whose key (case-insensitive) is one of
    ``keys``, else None."""
    m = _KEY_VALUE.match(text)
    if m and m.group(1).lower() in keys:
        return m.group(1).lower(), m.group(2)
    return None


def _number(path, where: str, key: str, value: str, expected: str) -> float:
    """The finite number a TEXT ``key=value`` gives; a one-line error naming ``where`` (the
    layer, level or stair) and the value otherwise."""
    try:
        v = float(value)
    except ValueError:
        raise RoomFileError(f"{path}: {where}: {key}={value!r} is not a number (expected "
                            f"{expected})") from None
    if not math.isfinite(v):
        raise RoomFileError(f"{path}: {where}: {key}={value!r} is not a finite number "
                            f"(expected {expected})")
    return v


def _start_params(path, layer: str, texts: list[str]) -> dict[str, Any]:
    params: dict[str, Any] = {}
    for t in texts:
        kv = _key_value(t, _START_KEYS)
        if kv is None:
            raise RoomFileError(
                f"{path}: layer '{layer}': cannot read start parameter text {t!r} "
                "(expected count=N, spacing=S or density=D)"
            )
        key, value = kv
        params[key] = _number(path, f"layer '{layer}'", key, value,
                              "count=N, spacing=S [m] or density=D [ped/m^2]")
    if "count" in params and params["count"].is_integer():
        params["count"] = int(params["count"])  # (else the start area says: a whole number)
    return params or {"spacing": 1.0}


def _entities(path):
    """Every entity of the drawing's model space as (layer, kind, points, closed) or
    (layer, "TEXT", text); a one-line error for an unreadable file."""
    import ezdxf
    import ezdxf.path

    p = existing_file(path)
    try:
        doc = ezdxf.readfile(p)
    except (ezdxf.DXFError, OSError, UnicodeDecodeError, ValueError) as exc:
        detail = str(exc).replace(str(p), "").replace("File '' ", "").strip()
        raise RoomFileError(f"{path}: not a valid DXF file ({detail})") from None
    out = []
    for ent in doc.modelspace():
        layer = ent.dxf.layer
        kind = ent.dxftype()
        if kind in ("TEXT", "MTEXT"):
            out.append((layer, "TEXT", ent.plain_text() if kind == "MTEXT" else ent.dxf.text))
            continue
        try:
            ph = ezdxf.path.make_path(ent)
        except TypeError:
            out.append((layer, kind, None, False))
            continue
        pts = [(float(v.x), float(v.y)) for v in ph.flattening(FLATTEN_DISTANCE)]
        closed = ph.is_closed or (len(pts) > 2 and pts[0] == pts[-1])
        out.append((layer, kind, pts, closed))
    return p, out


def _room_native(path, ents, default_name: str, level: str | None = None) -> dict[str, Any]:
    """The native dict of one room (or one level's room) from its entities (layers without
    the level prefix)."""
    shapes: dict[str, list[tuple[str | None, list, str]]] = {r: [] for r in _ROLES}
    texts: dict[str, list[str]] = {}
    for ent in ents:
        layer = ent[0]
        rn = _role(layer)
        if rn is None:
            continue
        role, name = rn
        if ent[1] == "TEXT":
            texts.setdefault(layer, []).append(ent[2])
            continue
        shown = f"{level}.{layer}" if level else layer
        if ent[2] is None:
            raise RoomFileError(f"{path}: layer '{shown}': unsupported entity {ent[1]} for a "
                                f"{role}")
        if _ROLES[role][1] and not ent[3]:
            raise RoomFileError(f"{path}: layer '{shown}': a {role} must be a closed polyline")
        shapes[role].append((name, ent[2], layer))
    rooms = shapes["room"]
    where = f" of level '{level}'" if level else ""
    if not rooms:
        raise RoomFileError(f"{path}: no closed polyline on a 'room' layer{where} (the outer "
                            "walls)")
    if len(rooms) > 1:
        raise RoomFileError(f"{path}: {len(rooms)} polylines on 'room' layers{where}; "
                            "expected one")
    native: dict[str, Any] = {"outline": rooms[0][1], "name": rooms[0][0] or default_name}
    room_texts = texts.get(rooms[0][2], [])
    if level is not None:
        z = [kv[1] for kv in (_key_value(x, _LEVEL_KEYS) for x in room_texts) if kv]
        if len(z) != 1:
            raise RoomFileError(f"{path}: level '{level}': its room layer needs one TEXT "
                                f"'z=HEIGHT' (the level's height in m), got {len(z)}")
        native["z"] = _number(path, f"level '{level}' (layer '{level}.{rooms[0][2]}')", "z",
                              z[0], "z=HEIGHT, the level's height in m")
        native["name"] = level
        room_texts = [x for x in room_texts
                      if _key_value(x, _LEVEL_KEYS + _STAIR_KEYS) is None]
    if room_texts and level is None:
        native["description"] = "\n".join(room_texts)
    for role, (key, _closed) in _ROLES.items():
        if key is None:
            continue
        coord_key = "polygon" if _ROLES[role][1] else "polyline"
        bases = [name or role.replace("_", "-") for name, _, _ in shapes[role]]
        seen: dict[str, int] = {}
        for base, (_, pts, layer) in zip(bases, shapes[role]):
            seen[base] = seen.get(base, 0) + 1
            # repeated names (two entities on one layer): door-1, door-2
            name = f"{base}-{seen[base]}" if bases.count(base) > 1 else base
            el: dict[str, Any] = {coord_key: pts, "name": name}
            if role == "start":
                shown = f"{level}.{layer}" if level else layer
                el.update(_start_params(path, shown, texts.get(layer, [])))
            native.setdefault(key, []).append(el)
    return native


def read_dxf(path: str | Path) -> Room | Building:
    """Read a room (or a building) from a DXF file (see the module docstring for the layer
    rules)."""
    p, ents = _entities(path)
    levels: dict[str, list] = {}
    stairs: dict[str, dict[str, Any]] = {}
    plain = []
    for ent in ents:
        layer = ent[0]
        m = _STAIR_END.match(layer)
        if m:
            st = stairs.setdefault(m.group(1), {"texts": []})
            if ent[1] == "TEXT" or ent[2] is None or len(ent[2]) != 2:
                raise RoomFileError(f"{path}: layer '{layer}': a stair edge must be one LINE "
                                    "(two points)")
            st[m.group(2).lower()] = {"level": m.group(3), "edge": ent[2]}
            continue
        m = _STAIR.match(layer)
        if m and "." not in layer:
            st = stairs.setdefault(m.group(1), {"texts": []})
            if ent[1] == "TEXT":
                st["texts"].append(ent[2])
            elif ent[2] is None or not ent[3]:
                raise RoomFileError(f"{path}: layer '{layer}': a stair must be a closed "
                                    "polyline")
            else:
                st["polygon"] = ent[2]
            continue
        if "." in layer:
            level, _, rest = layer.partition(".")
            levels.setdefault(level, []).append((rest, *ent[1:]))
        else:
            plain.append(ent)
    if not levels and not stairs:
        return room_from_dict(_room_native(path, plain, p.stem), str(path))
    if any(_role(e[0]) is not None for e in plain):
        raise RoomFileError(f"{path}: a building's layers go under a level's name "
                            f"('LEVEL.room', ...), but layer '{plain[0][0]}' has none")
    data: dict[str, Any] = {"name": p.stem, "levels": [], "stairs": []}
    for name, lv_ents in levels.items():
        data["levels"].append(_room_native(path, lv_ents, name, level=name))
    for name, st in stairs.items():
        for key in ("polygon", "bottom", "top"):
            if key not in st:
                raise RoomFileError(f"{path}: stair '{name}' has no {key} (layers 'stair-NAME',"
                                    " 'stair-NAME.bottom-LEVEL', 'stair-NAME.top-LEVEL')")
        item = {"name": name, "polygon": st["polygon"], "bottom": st["bottom"],
                "top": st["top"]}
        for text in st["texts"]:
            kv = _key_value(text, _STAIR_KEYS)
            if kv is None:
                raise RoomFileError(f"{path}: stair '{name}': cannot read {text!r} (expected "
                                    "speed_up=F or speed_down=F)")
            item[kv[0]] = _number(path, f"stair '{name}'", *kv,
                                  f"{kv[0]}=F, a fraction of the free speed")
        data["stairs"].append(item)
    return room_from_dict(data, str(path))


def write_dxf(room: Room | Building, path: str | Path) -> None:
    """Write a room (or a building) as a DXF drawing with one layer per element."""
    import ezdxf

    from ..site import is_building

    doc = ezdxf.new("R2010")
    doc.units = ezdxf.units.M
    msp = doc.modelspace()

    def add(layer: str, pts: list, closed: bool) -> None:
        if layer not in doc.layers:
            doc.layers.add(layer)
        msp.add_lwpolyline([tuple(p) for p in pts], close=closed, dxfattribs={"layer": layer})

    if is_building(room):
        b = building_to_dict(room)
        for lv, level in zip(b["levels"], room.levels):
            _write_room(msp, add, lv, f"{lv['name']}.", "room", level.room.description)
            x, y = lv["outline"][0]
            msp.add_text(f"z={lv['z']!r}", dxfattribs={"layer": f"{lv['name']}.room",
                                                       "insert": (x, y)})
        for s in b["stairs"]:
            add(f"stair-{s['name']}", s["polygon"], True)
            for end in ("bottom", "top"):
                add(f"stair-{s['name']}.{end}-{s[end]['level']}", s[end]["edge"], False)
            x, y = s["polygon"][0]
            for k in ("speed_up", "speed_down"):
                msp.add_text(f"{k}={s[k]!r}", dxfattribs={"layer": f"stair-{s['name']}",
                                                          "insert": (x, y)})
        doc.saveas(Path(path))
        return
    d = room_to_dict(room)
    room_layer = f"room-{room.name}" if room.name else "room"
    _write_room(msp, add, d, "", room_layer, room.description)
    doc.saveas(Path(path))


def _write_room(msp, add, d: dict, prefix: str, room_layer: str, description: str) -> None:
    """The layers of one room's native dict ``d`` (a level's under ``prefix``)."""
    add(prefix + room_layer, d["outline"], True)
    if description:
        x, y = d["outline"][0]
        msp.add_mtext(description, dxfattribs={"layer": prefix + room_layer,
                                               "insert": (x, y)})
    for role, (key, closed) in _ROLES.items():
        if key is None:
            continue
        coord_key = "polygon" if closed else "polyline"
        for el in d.get(key, []):
            layer = f"{prefix}{role}-{el['name']}"
            add(layer, el[coord_key], closed)
            if role == "start":
                for k in ("count", "spacing", "density"):
                    if k in el:
                        x, y = el[coord_key][0]
                        msp.add_text(f"{k}={el[k]!r}",
                                     dxfattribs={"layer": layer, "insert": (x, y)})


register_format(RoomFormat("dxf", (".dxf",), read_dxf, write_dxf))
