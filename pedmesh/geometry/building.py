"""Buildings: levels at their heights joined by stairs, all on one walkable surface.

A :class:`Building` is a list of :class:`Level` objects, each a :class:`~pedmesh.geometry.Room`
(outline, obstacles, exits, start areas, measurement elements) at a height ``z`` [m], and a
list of :class:`Stair` objects. A stair is one inclined plane: a plan polygon whose
``bottom`` edge meets one level's outline and whose ``top`` edge meets another's, each an
opening in that level's wall. The plane through the two edges fixes the stair's slope; a
stair with zero rise is a flat connector between two pieces (a landing is a small level of
its own). Levels may overlap each other in plan (stacked floors).

The native JSON format (:mod:`pedmesh.geometry.formats.native`) writes a building as::

    {"name": "office", "levels": [{"name": "ground", "z": 0.0, "outline": [...],
                                   "exits": [...], "start_areas": [...]}, ...],
     "stairs": [{"name": "stair-west", "polygon": [[x, y], ...],
                 "bottom": {"level": "ground", "edge": [[x, y], [x, y]]},
                 "top": {"level": "first", "edge": [[x, y], [x, y]]},
                 "speed_up": 0.5, "speed_down": 0.6}]}

``speed_up``/``speed_down`` are the desired speed on the stair, going up or down, as a
fraction of the level's desired speed (defaults: :data:`STAIR_SPEED_UP`,
:data:`STAIR_SPEED_DOWN`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
from shapely.geometry import LinearRing, LineString, Polygon

from ..errors import GeometryError
from .room import (_COORDINATE_LIMITS, MAX_COORDINATE, Points, Room, _check_name, _check_preset,
                   _check_seed,
                   _coerce_points, _is_real, _polygon)
from .tolerances import EXIT_TOLERANCE

__all__ = ["Building", "Level", "Stair", "StairEnd", "STAIR_SPEED_UP", "STAIR_SPEED_DOWN",
           "MAX_STAIR_SLOPE_DEG"]

#: desired speed on a stair going up, as a fraction of the free speed on the level, along
#: the slope. Weidmann (1993) gives 0.61 m/s up and 0.694 m/s down, horizontal components
#: on common stairs (about 30 degrees): 0.70 and 0.80 m/s along the slope, 0.52 and 0.60 of
#: his free speed of 1.34 m/s. Fruin (1971), measured along the slope: 0.49-0.67 m/s up and
#: 0.60-1.01 m/s down. JuPedSim 0.x defaults to 0.6 m/s both ways (horizontal). Long stairs
#: are slower (Kretz et al. 2008: 0.4-0.5 m/s up, horizontal).
STAIR_SPEED_UP = 0.5
#: desired speed on a stair going down, as a fraction of the free speed on the level, along
#: the slope (see :data:`STAIR_SPEED_UP`)
STAIR_SPEED_DOWN = 0.6
#: [degrees] the steepest stair (45 degrees: a rise as long as its run)
MAX_STAIR_SLOPE_DEG = 45.0


def _fraction(value: Any, what: str, label: str) -> float:
    if not _is_real(value) or not math.isfinite(value) or not 0.0 < value <= 2.0:
        raise GeometryError(f"{label}: {what} must be a fraction of the free speed in (0, 2], "
                            f"got {value!r}")
    return float(value)


@dataclass(frozen=True)
class StairEnd:
    """Where a stair meets a level: the level's name and the segment (two plan points [m])
    of the level's outline that is the opening."""

    level: str
    edge: Points

    def __post_init__(self) -> None:
        if not isinstance(self.level, str) or not self.level:
            raise GeometryError(f"stair end: 'level' must be a level's name, got {self.level!r}")
        pts = _coerce_points(self.edge, f"stair end at level '{self.level}'", ring=False)
        if len(pts) != 2:
            raise GeometryError(f"stair end at level '{self.level}': 'edge' must be two "
                                f"points [[x, y], [x, y]], got {len(pts)}")
        object.__setattr__(self, "edge", pts)

    @property
    def length(self) -> float:
        (x0, y0), (x1, y1) = self.edge
        return math.hypot(x1 - x0, y1 - y0)


@dataclass(frozen=True)
class Stair:
    """One inclined plane between two levels (see the module docstring)."""

    name: str
    polygon: Points
    bottom: StairEnd
    top: StairEnd
    speed_up: float = STAIR_SPEED_UP
    speed_down: float = STAIR_SPEED_DOWN

    def __post_init__(self) -> None:
        _check_name(self.name, "stair")
        label = f"stair '{self.name}'"
        object.__setattr__(self, "polygon", _coerce_points(self.polygon, label, ring=True))
        _polygon(self.polygon, label)
        for key in ("bottom", "top"):
            end = getattr(self, key)
            if isinstance(end, dict):
                bad = sorted(set(end) - {"level", "edge"})
                if bad:
                    raise GeometryError(f"{label}: unknown key '{bad[0]}' in '{key}' "
                                        "(allowed: edge, level)")
                if "level" not in end or "edge" not in end:
                    raise GeometryError(f"{label}: '{key}' needs 'level' and 'edge'")
                try:
                    end = StairEnd(end["level"], end["edge"])
                except GeometryError as exc:
                    raise GeometryError(f"{label}: {key}: {exc}") from None
            elif not isinstance(end, StairEnd):
                raise GeometryError(f"{label}: '{key}' must be {{\"level\": NAME, \"edge\": "
                                    f"[[x, y], [x, y]]}}, got {end!r}")
            object.__setattr__(self, key, end)
        object.__setattr__(self, "speed_up", _fraction(self.speed_up, "speed_up", label))
        object.__setattr__(self, "speed_down", _fraction(self.speed_down, "speed_down",
                                                         label))
        shape = self.shape
        for key in ("bottom", "top"):
            edge = LineString(getattr(self, key).edge)
            if edge.difference(shape.exterior.buffer(EXIT_TOLERANCE)).length > EXIT_TOLERANCE:
                raise GeometryError(f"{label}: its {key} edge does not lie on the stair's "
                                    "polygon")
        if LineString(self.bottom.edge).distance(LineString(self.top.edge)) <= EXIT_TOLERANCE:
            raise GeometryError(f"{label}: its bottom and top edges touch")

    @cached_property
    def shape(self) -> Polygon:
        """The stair's plan polygon [m]."""
        return Polygon(self.polygon)

    def run_direction(self) -> tuple[np.ndarray, float]:
        """The unit plan direction d from the bottom edge towards the top edge
        (perpendicular to both) and the run [m]: the plan distance between them."""
        (x0, y0), (x1, y1) = self.bottom.edge
        t = np.array([x1 - x0, y1 - y0]) / self.bottom.length
        d = np.array([-t[1], t[0]])
        mid = np.mean(np.asarray(self.top.edge), axis=0)
        run = float(np.dot(mid - np.array([x0, y0]), d))
        if run < 0:
            d, run = -d, -run
        return d, run


@dataclass(frozen=True)
class Level:
    """A floor of the building: a room at height ``z`` [m]."""

    name: str
    z: float
    room: Room

    def __post_init__(self) -> None:
        _check_name(self.name, "level")
        if not _is_real(self.z) or not abs(self.z) <= MAX_COORDINATE:  # (nan fails too)
            raise GeometryError(f"level '{self.name}': 'z' must be a finite height in m "
                                f"within {_COORDINATE_LIMITS}, got {self.z!r}")
        object.__setattr__(self, "z", float(self.z))
        if not isinstance(self.room, Room):
            raise GeometryError(f"level '{self.name}': its room must be a Room")


@dataclass(frozen=True)
class Building:
    """Levels joined by stairs (see the module docstring)."""

    levels: tuple[Level, ...]
    stairs: tuple[Stair, ...] = ()
    name: str = "building"
    description: str = ""
    preset: str | None = None
    #: the random seed of its particle model runs unless told otherwise (see Room.seed)
    seed: int | None = None
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "levels", tuple(self.levels))
        object.__setattr__(self, "stairs", tuple(self.stairs))
        if not self.levels:
            raise GeometryError("a building needs at least one level")
        for kind, items in (("level", self.levels), ("stair", self.stairs)):
            names = [x.name for x in items]
            for n in names:
                if names.count(n) > 1:
                    raise GeometryError(f"{kind} name '{n}' is used more than once")
        exits = [e.name for lv in self.levels for e in lv.room.exits]
        for n in exits:
            if exits.count(n) > 1:
                raise GeometryError(f"exit name '{n}' is used on more than one level (exit "
                                    "names must be unique in a building)")
        _check_preset(self.preset)
        _check_seed(self.seed)
        known = set(exits)
        for lv in self.levels:
            for a in lv.room.start_areas:
                for e, _ in a.exits or ():
                    if e not in known:
                        raise GeometryError(f"level '{lv.name}': start area '{a.name}': "
                                            f"'exits' names '{e}', which is not an exit of "
                                            f"the building (exits: {', '.join(sorted(known))})")
        for s in self.stairs:
            self._check_stair(s)
        self._check_stair_openings()

    def no_way_out(self) -> list[tuple[str, str, str]]:
        """(level, start area, why) of every start area whose people can never leave: no
        stair leads from its level to a level with an exit (or to one of the exits the area
        names)."""
        adj: dict[str, set[str]] = {lv.name: set() for lv in self.levels}
        for st in self.stairs:
            adj[st.bottom.level].add(st.top.level)
            adj[st.top.level].add(st.bottom.level)
        exit_level = {e.name: lv.name for lv in self.levels for e in lv.room.exits}
        out = []
        for lv in self.levels:
            if not lv.room.start_areas:
                continue
            seen, todo = {lv.name}, [lv.name]
            while todo:
                for n in adj[todo.pop()] - seen:
                    seen.add(n)
                    todo.append(n)
            for a in lv.room.start_areas:
                wanted = [e for e, _ in a.exits or ()] or list(exit_level)
                if not any(exit_level[e] in seen for e in wanted):
                    what = ("the exits it names" if a.exits else "a level with an exit")
                    why = (f"no stair leads from level '{lv.name}' to {what}" if exit_level
                           else "the building has no exit")
                    out.append((lv.name, a.name, why))
        return out

    # ------------------------------------------------------------------ checks
    def level(self, name: str) -> Level:
        """The level called ``name``."""
        for lv in self.levels:
            if lv.name == name:
                return lv
        raise GeometryError(f"building '{self.name}' has no level '{name}' (levels: "
                            f"{', '.join(lv.name for lv in self.levels)})")

    def _check_stair(self, s: Stair) -> None:
        label = f"stair '{s.name}'"
        for key in ("bottom", "top"):
            end = getattr(s, key)
            try:
                lv = self.level(end.level)
            except GeometryError as exc:
                raise GeometryError(f"{label}: {key}: {exc}") from None
            ring = LinearRing(lv.room.outline)
            edge = LineString(end.edge)
            off = edge.difference(ring.buffer(EXIT_TOLERANCE)).length
            if off > EXIT_TOLERANCE:
                raise GeometryError(f"{label}: its {key} edge is not on the outline of level "
                                    f"'{lv.name}' (it must be an opening in that level's "
                                    "wall)")
            for ex in lv.room.exits:
                if ex.shape.intersection(edge).length > EXIT_TOLERANCE:
                    raise GeometryError(f"{label}: its {key} edge overlaps exit '{ex.name}' "
                                        f"of level '{lv.name}'")
            if s.shape.intersection(lv.room.walkable).area > 1e-9:
                raise GeometryError(f"{label} overlaps the walkable area of level "
                                    f"'{lv.name}' (a stair lies outside the levels it joins)")
        if s.bottom.level == s.top.level:
            raise GeometryError(f"{label}: its bottom and top are on the same level "
                                f"'{s.bottom.level}'")
        rise = self.rise(s)
        if rise < 0:
            raise GeometryError(f"{label}: its top level '{s.top.level}' is below its bottom "
                                f"level '{s.bottom.level}'")
        (b0, b1), (t0, t1) = np.asarray(s.bottom.edge), np.asarray(s.top.edge)
        tb = (b1 - b0) / np.linalg.norm(b1 - b0)
        tt = (t1 - t0) / np.linalg.norm(t1 - t0)
        if rise > 0 and abs(tb[0] * tt[1] - tb[1] * tt[0]) > 1e-6:
            raise GeometryError(f"{label}: its bottom and top edges must be parallel (a stair "
                                "is one inclined plane, and its horizontal lines are "
                                "parallel)")
        d, run = s.run_direction()
        lo, hi = self._extent(s, d)
        if lo < -EXIT_TOLERANCE or hi > run + EXIT_TOLERANCE:
            raise GeometryError(f"{label}: its polygon reaches beyond its bottom or top edge "
                                "(the stair lies between them)")
        slope = math.degrees(math.atan2(rise, run))
        if slope > MAX_STAIR_SLOPE_DEG + 1e-9:
            raise GeometryError(f"{label} is steeper than {MAX_STAIR_SLOPE_DEG:g} degrees "
                                f"({slope:.1f}: a rise of {rise:g} m over a run of "
                                f"{run:g} m)")

    def _check_stair_openings(self) -> None:
        """A one-line error if two stairs' edges overlap on a level: each stair joins the
        level through its own opening in the wall (two stairs sharing one would join each
        other there, past the level)."""
        ends = [(s, key, getattr(s, key)) for s in self.stairs for key in ("bottom", "top")]
        for a in range(len(ends)):
            for b in range(a + 1, len(ends)):
                (sa, ka, ea), (sb, kb, eb) = ends[a], ends[b]
                if sa is sb or ea.level != eb.level:
                    continue
                common = LineString(ea.edge).intersection(LineString(eb.edge)).length
                if common > EXIT_TOLERANCE:
                    raise GeometryError(
                        f"stair '{sa.name}': its {ka} edge overlaps the {kb} edge of stair "
                        f"'{sb.name}' on level '{ea.level}' ({common:g} m in common; each "
                        "stair needs its own opening in the level's wall)")

    @staticmethod
    def _extent(s: Stair, d: np.ndarray) -> tuple[float, float]:
        p = np.asarray(s.polygon) - np.asarray(s.bottom.edge[0])
        proj = p @ d
        return float(proj.min()), float(proj.max())

    # ------------------------------------------------------------------ derived
    def rise(self, s: Stair) -> float:
        """The height [m] a stair climbs from its bottom level to its top level."""
        return self.level(s.top.level).z - self.level(s.bottom.level).z

    def slope(self, s: Stair) -> float:
        """The stair's slope angle [degrees]."""
        _, run = s.run_direction()
        return math.degrees(math.atan2(self.rise(s), run))

    def stair_height(self, s: Stair, xy: np.ndarray) -> np.ndarray:
        """The height z [m] of the stair's plane at plan points ``xy`` (k, 2)."""
        d, run = s.run_direction()
        z0 = self.level(s.bottom.level).z
        along = (np.asarray(xy, float) - np.asarray(s.bottom.edge[0])) @ d
        return z0 + self.rise(s) * along / run

    @property
    def exit_names(self) -> tuple[str, ...]:
        return tuple(e.name for lv in self.levels for e in lv.room.exits)

    @property
    def start_areas(self) -> tuple:
        """Every level's start areas, level by level (:attr:`start_area_levels` names the
        level of each)."""
        return tuple(a for lv in self.levels for a in lv.room.start_areas)

    @property
    def start_area_levels(self) -> tuple[str, ...]:
        """The level of each of :attr:`start_areas`."""
        return tuple(lv.name for lv in self.levels for _ in lv.room.start_areas)

    @property
    def area(self) -> float:
        """The walkable area [m^2] on the surface: the levels' and the stairs' true (sloped)
        areas."""
        a = sum(lv.room.area for lv in self.levels)
        for s in self.stairs:
            _, run = s.run_direction()
            a += s.shape.area * math.hypot(run, self.rise(s)) / run
        return a
