"""Rooms from SVG floor plans, by element id or label (geometry through trimesh).

An element's Inkscape label (``inkscape:label``) or else its ``id`` gives its role, as DXF
layers do: ``room``, ``obstacle``, ``exit``, ``start``, ``measurement_line`` or
``measurement_area``, optionally followed by ``-NAME`` or ``_NAME`` (``obstacle-pillar1``,
``exit_north``). Other ids are ignored, except near misses of a role (``exits``,
``obstacles-a``, ``exit1``, ``measurement-door``), which are errors rather than silently
dropped. An
element without a role of its own takes the role of the nearest group (``<g>``, e.g. an
Inkscape layer) that has one: a group ``obstacle`` holding ten ``rect`` elements gives ten
obstacles, named by their own labels or ids where those are not an editor's automatic ones
(``rect12``). Elements with no role on them or their groups are ignored. The ``room`` may be
a compound path (an outline with holes, as Inkscape's Path > Difference makes): its largest
ring is the outline and the others are obstacles.

Shapes: ``rect``, ``polygon``, ``polyline``, ``line``, ``circle`` and ``path`` (lines,
arcs and Bezier curves), with their ``transform`` attributes and those of their groups;
trimesh (``trimesh.load_path``) parses them; curves are kept to within 1 cm. Polygons (room,
obstacle, start, measurement area) must be closed. A start area takes ``data-count``,
``data-spacing`` [m] or ``data-density`` [ped/m^2] from its element or group (default
``spacing=1``).

Units and axes: one SVG user unit is one metre unless the root ``<svg>`` element says
otherwise with ``data-pedmesh-scale`` (metres per user unit, e.g. ``0.01`` for a drawing in
centimetres). SVG's y axis points down; pedmesh's points up, so y is flipped: a point at
SVG (x, y) is at (x, y_max - y) times the scale, y_max being the room's lowest point in the
picture. The room is not mirrored: the top of the picture is the largest y, and the room's
bottom edge is at y = 0.
"""

from __future__ import annotations

import copy
import difflib
import io
import math
import re
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import RoomFileError
from ..room import Room
from ._registry import RoomFormat, existing_file, register_format
from .dxf import _ROLES, FLATTEN_DISTANCE, _role
from .native import room_from_dict

__all__ = ["read_svg"]

SVG_NS = "http://www.w3.org/2000/svg"
_INKSCAPE_LABEL = "{http://www.inkscape.org/namespaces/inkscape}label"
_SHAPES = {"rect", "polygon", "polyline", "line", "circle", "ellipse", "path"}
_AUTO_ID = re.compile(r"^(rect|path|circle|ellipse|polygon|polyline|line|svg_?)\d+$")
_NUMBER = re.compile(r"^\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*$")


def _tag(el: ET.Element) -> str:
    return el.tag.rsplit("}", 1)[-1]


def _label(el: ET.Element) -> str | None:
    return el.get(_INKSCAPE_LABEL) or el.get("id")


_ROLE_WORDS = ("room", "obstacle", "exit", "start", "measurement")
_ROLE_LIST = "room, obstacle, exit, start, measurement_line, measurement_area"


def _role_of(path, el: ET.Element) -> tuple[str, str | None] | None:
    """(role, name or None) from the element's Inkscape label or else its id; None if neither
    names a role. A near miss of a role (``exits``, ``obstacle1``) is an error."""
    for text in (el.get(_INKSCAPE_LABEL), el.get("id")):
        if not text:
            continue
        found = _role(text)
        if found is not None:
            return found
        word = re.split(r"[-_\s]", text.strip().lower(), maxsplit=1)[0]
        near = difflib.get_close_matches(word, _ROLE_WORDS, n=1, cutoff=0.85)
        if near:
            raise RoomFileError(f"{path}: element '{text}' (<{_tag(el)}>): unknown role; "
                                f"the roles are {_ROLE_LIST}, each optionally followed by "
                                "-NAME")
    return None


def _ring_area(pts: np.ndarray) -> float:
    x, y = pts[:, 0], pts[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def _walk(el: ET.Element, ancestors: list[ET.Element], out: list) -> None:
    for child in el:
        tag = _tag(child)
        if tag in _SHAPES:
            out.append((child, list(ancestors)))
        elif tag in ("g", "a", "switch"):
            _walk(child, [*ancestors, child], out)


def _polylines(path, el: ET.Element, ancestors: list[ET.Element]) -> list[np.ndarray]:
    """The element's outline(s) in SVG user units, with its groups' transforms, through
    trimesh: one (n, 2) array per connected piece."""
    import trimesh

    doc = ET.Element(f"{{{SVG_NS}}}svg")
    parent = doc
    for a in ancestors:
        if a.get("transform"):
            parent = ET.SubElement(parent, f"{{{SVG_NS}}}g", transform=a.get("transform"))
    leaf = copy.copy(el)
    leaf[:] = []
    parent.append(leaf)
    try:
        loaded = trimesh.load_path(io.BytesIO(ET.tostring(doc)), file_type="svg")
    except Exception as exc:  # trimesh's parser raises many kinds
        raise RoomFileError(f"{path}: element '{_label(el)}': cannot read its geometry "
                            f"({type(exc).__name__}: {exc})") from None
    if loaded is None or len(getattr(loaded, "entities", [])) == 0:
        return []
    pieces: list[list[np.ndarray]] = []
    for ent in loaded.entities:
        pts = np.asarray(ent.discrete(loaded.vertices), float)[:, :2]
        if pieces and np.allclose(pieces[-1][-1][-1], pts[0], atol=1e-9):
            pieces[-1].append(pts[1:])
        else:
            pieces.append([pts])
    return [np.vstack(p) for p in pieces]


def _flatten(pts: np.ndarray, tol: float) -> np.ndarray:
    """Drop points that are within ``tol`` of the polyline without them (trimesh flattens
    curves far finer than a room needs: thousands of points on a pillar)."""
    import shapely

    if len(pts) < 4:
        return pts
    simple = shapely.LineString(pts).simplify(tol, preserve_topology=True)
    return np.asarray(simple.coords, float)


def _param(path, el: ET.Element, groups: list[ET.Element]) -> dict[str, Any]:
    for holder in (el, *reversed(groups)):
        found = {k: holder.get(f"data-{k}") for k in ("count", "spacing", "density")
                 if holder.get(f"data-{k}") is not None}
        if len(found) > 1:
            raise RoomFileError(f"{path}: start area '{_label(el)}': give one of data-count, "
                                "data-spacing, data-density")
        for k, v in found.items():
            if not _NUMBER.match(v):
                raise RoomFileError(f"{path}: start area '{_label(el)}': data-{k}={v!r} is not "
                                    "a number")
            if k == "count" and not float(v).is_integer():
                raise RoomFileError(f"{path}: start area '{_label(el)}': data-count={v!r} is "
                                    "not a whole number")
            return {k: int(float(v)) if k == "count" else float(v)}
    return {"spacing": 1.0}


def read_svg(path: str | Path) -> Room:
    """Read a room from an SVG floor plan (see the module docstring for the rules)."""
    p = existing_file(path)
    try:  # trimesh's SVG reader needs both; without them every element would fail alike
        import lxml.etree  # noqa: F401
        import svg.path  # noqa: F401
    except ImportError as exc:
        raise RoomFileError(f"{path}: reading SVG rooms needs the packages lxml and svg.path "
                            f"(pip install lxml svg.path): {exc}") from None
    try:
        root = ET.parse(p).getroot()
    except ET.ParseError as exc:
        raise RoomFileError(f"{path}: not a valid SVG file ({exc})") from None
    if _tag(root) != "svg":
        raise RoomFileError(f"{path}: not an SVG file (its root element is <{_tag(root)}>)")
    scale_text = root.get("data-pedmesh-scale", "1")
    if not _NUMBER.match(scale_text) or not (float(scale_text) > 0
                                             and math.isfinite(float(scale_text))):
        raise RoomFileError(f"{path}: data-pedmesh-scale={scale_text!r} must be a positive "
                            "number (metres per SVG unit)")
    scale = float(scale_text)
    found: list[tuple[ET.Element, list[ET.Element]]] = []
    _walk(root, [], found)
    shapes: dict[str, list[tuple[str | None, np.ndarray, ET.Element, list]]] = {
        r: [] for r in _ROLES}
    group_roles = {id(g): _role_of(path, g) for _, groups in found for g in groups}
    for el, groups in found:
        role_name = _role_of(path, el)
        holders = [g for g in groups if group_roles[id(g)]]
        if role_name is None and holders:
            role, gname = group_roles[id(holders[-1])]
            own = _label(el)
            role_name = (role, own if own and not _AUTO_ID.match(own) else gname)
        if role_name is None:
            continue
        role, name = role_name
        lines = _polylines(path, el, groups)
        if not lines:
            raise RoomFileError(f"{path}: element '{_label(el)}' (<{_tag(el)}>): no geometry "
                                "pedmesh can read (use rect, polygon, polyline, line, circle "
                                "or path)")
        for pts in lines:
            pts = _flatten(pts, FLATTEN_DISTANCE / scale)
            closed = len(pts) > 2 and np.allclose(pts[0], pts[-1], atol=1e-9)
            if _ROLES[role][1] and not closed:
                raise RoomFileError(f"{path}: element '{_label(el)}': a {role} must be a closed "
                                    "shape (rect, polygon, circle or a closed path)")
            if closed:
                pts = pts[:-1]
            shapes[role].append((name, pts, el, groups))
    rooms = shapes["room"]
    if not rooms:
        raise RoomFileError(f"{path}: no element with id or label 'room' (the outer walls)")
    n_elements = len({id(el) for _, _, el, _ in rooms})
    if n_elements > 1:
        raise RoomFileError(f"{path}: {n_elements} elements have the role 'room' ("
                            f"{', '.join(repr(_label(r[2])) for r in rooms)}); expected one")
    if len(rooms) > 1:  # a compound path: the largest ring is the outline, the rest holes
        rooms.sort(key=lambda r: _ring_area(r[1]), reverse=True)
        shapes["obstacle"][:0] = [(None, pts, el, groups) for _, pts, el, groups in rooms[1:]]
    top = float(rooms[0][1][:, 1].max())

    def to_m(pts: np.ndarray) -> list[tuple[float, float]]:
        return [(float(x * scale), float((top - y) * scale)) for x, y in pts]

    native: dict[str, Any] = {"outline": to_m(rooms[0][1]), "name": rooms[0][0] or p.stem}
    for role, (key, closed) in _ROLES.items():
        if key is None:
            continue
        coord_key = "polygon" if closed else "polyline"
        bases = [name or role.replace("_", "-") for name, *_ in shapes[role]]
        seen: dict[str, int] = {}
        for base, (_, pts, el, groups) in zip(bases, shapes[role]):
            seen[base] = seen.get(base, 0) + 1
            name = f"{base}-{seen[base]}" if bases.count(base) > 1 else base
            item: dict[str, Any] = {coord_key: to_m(pts), "name": name}
            if role == "start":
                item.update(_param(path, el, groups))
            native.setdefault(key, []).append(item)
    return room_from_dict(native, str(path))


register_format(RoomFormat("svg", (".svg",), read_svg, None))
