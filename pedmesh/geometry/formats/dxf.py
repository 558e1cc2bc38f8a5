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
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from ...errors import RoomFileError
from ..room import Room
from ._registry import RoomFormat, existing_file, register_format
from .native import room_from_dict, room_to_dict

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
_PARAM = re.compile(r"^\s*(count|spacing|density)\s*=\s*([-+0-9.eE]+)\s*$")


def _role(layer: str) -> tuple[str, str | None] | None:
    low = layer.lower().replace("-", "_")
    for role in _ROLES:  # longest roles first, so measurement_* wins over other prefixes
        if low == role:
            return role, None
        if low.startswith(role + "_") and len(layer) > len(role) + 1:
            return role, layer[len(role) + 1 :]
    return None


def _start_params(path, layer: str, texts: list[str]) -> dict[str, Any]:
    params: dict[str, Any] = {}
    for t in texts:
        m = _PARAM.match(t)
        if not m:
            raise RoomFileError(
                f"{path}: layer '{layer}': cannot read start parameter text {t!r} "
                "(expected count=N, spacing=S or density=D)"
            )
        params[m.group(1)] = float(m.group(2))
    if "count" in params:
        params["count"] = int(params["count"])
    return params or {"spacing": 1.0}


def read_dxf(path: str | Path) -> Room:
    """Read a room from a DXF file (see the module docstring for the layer rules)."""
    import ezdxf
    import ezdxf.path

    p = existing_file(path)
    try:
        doc = ezdxf.readfile(p)
    except (ezdxf.DXFError, OSError, UnicodeDecodeError, ValueError) as exc:
        detail = str(exc).replace(str(p), "").replace("File '' ", "").strip()
        raise RoomFileError(f"{path}: not a valid DXF file ({detail})") from None
    shapes: dict[str, list[tuple[str | None, list, str]]] = {r: [] for r in _ROLES}
    texts: dict[str, list[str]] = {}
    for ent in doc.modelspace():
        layer = ent.dxf.layer
        rn = _role(layer)
        if rn is None:
            continue
        role, name = rn
        kind = ent.dxftype()
        if kind in ("TEXT", "MTEXT"):
            txt = ent.plain_text() if kind == "MTEXT" else ent.dxf.text
            texts.setdefault(layer, []).append(txt)
            continue
        try:
            ph = ezdxf.path.make_path(ent)
        except TypeError:
            raise RoomFileError(
                f"{path}: layer '{layer}': unsupported entity {kind} for a {role}"
            ) from None
        pts = [(float(v.x), float(v.y)) for v in ph.flattening(FLATTEN_DISTANCE)]
        closed = ph.is_closed or (len(pts) > 2 and pts[0] == pts[-1])
        if _ROLES[role][1] and not closed:
            raise RoomFileError(f"{path}: layer '{layer}': a {role} must be a closed polyline")
        shapes[role].append((name, pts, layer))
    rooms = shapes["room"]
    if not rooms:
        raise RoomFileError(f"{path}: no closed polyline on a 'room' layer (the outer walls)")
    if len(rooms) > 1:
        raise RoomFileError(f"{path}: {len(rooms)} polylines on 'room' layers; expected one")
    native: dict[str, Any] = {"outline": rooms[0][1], "name": rooms[0][0] or p.stem}
    room_texts = texts.get(rooms[0][2], [])
    if room_texts:
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
                el.update(_start_params(path, layer, texts.get(layer, [])))
            native.setdefault(key, []).append(el)
    return room_from_dict(native, str(path))


def write_dxf(room: Room, path: str | Path) -> None:
    """Write a room as a DXF drawing with one layer per element."""
    import ezdxf

    doc = ezdxf.new("R2010")
    doc.units = ezdxf.units.M
    msp = doc.modelspace()
    d = room_to_dict(room)

    def add(layer: str, pts: list, closed: bool) -> None:
        if layer not in doc.layers:
            doc.layers.add(layer)
        msp.add_lwpolyline([tuple(p) for p in pts], close=closed, dxfattribs={"layer": layer})

    room_layer = f"room-{room.name}" if room.name else "room"
    add(room_layer, d["outline"], True)
    if room.description:
        x, y = d["outline"][0]
        msp.add_mtext(room.description, dxfattribs={"layer": room_layer, "insert": (x, y)})
    for role, (key, closed) in _ROLES.items():
        if key is None:
            continue
        coord_key = "polygon" if closed else "polyline"
        for el in d.get(key, []):
            layer = f"{role}-{el['name']}"
            add(layer, el[coord_key], closed)
            if role == "start":
                for k in ("count", "spacing", "density"):
                    if k in el:
                        x, y = el[coord_key][0]
                        msp.add_text(f"{k}={el[k]!r}",
                                     dxfattribs={"layer": layer, "insert": (x, y)})
    doc.saveas(Path(path))


register_format(RoomFormat("dxf", (".dxf",), read_dxf, write_dxf))
