"""Rooms: walls, obstacles, exits, start areas and measurement elements, validated.

All coordinates are in metres. A :class:`Room` is immutable and validated on construction
with shapely; every failure raises :class:`~pedmesh.errors.GeometryError` with a message
that names the element and the problem.

Rules (checked in this order):

* coordinates are pairs of finite real numbers within +-:data:`MAX_COORDINATE` (1e7 m);
  consecutive duplicate points are dropped, and a closing point equal to the first point of
  a ring is dropped;
* rings (outline, obstacles, start and measurement areas) have at least three distinct
  points, are simple (no self-intersection) and enclose a positive area;
* obstacles lie strictly inside the outline (not touching it) and neither overlap nor touch
  each other (an obstacle that touches a wall belongs in the outline);
* an exit is a segment or polyline of positive length that lies on the outline or on one
  obstacle's boundary within :data:`EXIT_TOLERANCE` (1e-6 m); exits do not overlap;
* start areas lie in the walkable area (room minus obstacles) within the same tolerance and
  give exactly one of ``count`` (pedestrians), ``spacing`` [m] or ``density`` [ped/m^2],
  at most :data:`MAX_START_DENSITY` (10 /m^2) people per m^2; their people's ``speed``
  [m/s], ``radius`` [m] and ``premovement`` [s] lie in physical ranges
  (:data:`pedmesh.population.RANGES`);
* measurement lines and areas lie in the walkable area;
* names are non-empty and unique within their kind.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Iterable, Sequence

import numpy as np
import shapely
from shapely.geometry import LinearRing, LineString, Point, Polygon

from ..errors import GeometryError
from .tolerances import EXIT_TOLERANCE

__all__ = [
    "EXIT_TOLERANCE",
    "MAX_COORDINATE",
    "MAX_START_DENSITY",
    "Points",
    "Obstacle",
    "Exit",
    "StartArea",
    "MeasurementLine",
    "MeasurementArea",
    "Room",
]


Points = tuple[tuple[float, float], ...]

#: [m] the largest coordinate (in absolute value) a point may have: 10,000 km, more than any
#: site; far beyond it a float64 coordinate's resolution (2e-9 m at 1e7 m) nears the
#: 1e-6 m of :data:`EXIT_TOLERANCE` and areas, squares of lengths, lose their meaning
MAX_COORDINATE = 1e7
_COORDINATE_LIMITS = f"[-{MAX_COORDINATE:.0e}, {MAX_COORDINATE:.0e}]".replace("e+0", "e")
_COORDINATE_RANGE = f"coordinates must be finite and within {_COORDINATE_LIMITS} m"


# --------------------------------------------------------------------------- coercion
def _is_real(v: Any) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


def _coerce_points(value: Any, label: str, *, ring: bool) -> Points:
    """Turn ``value`` into a tuple of (x, y) float pairs, or raise a GeometryError."""
    if isinstance(value, Polygon):
        value = list(value.exterior.coords)
    elif isinstance(value, (LineString, LinearRing)):
        value = list(value.coords)
    elif isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (str, bytes)) or not isinstance(value, Iterable):
        raise GeometryError(f"{label}: coordinates must be a list of [x, y] pairs, got {value!r}")
    pts: list[tuple[float, float]] = []
    k = -1
    for k, p in enumerate(value):
        if isinstance(p, np.ndarray):
            p = p.tolist()
        if isinstance(p, (str, bytes)) or not isinstance(p, Sequence) or len(p) != 2:
            raise GeometryError(f"{label}: point {k} must be an [x, y] pair, got {p!r}")
        for c in p:
            if not _is_real(c):
                raise GeometryError(f"{label}: point {k} has a non-numeric coordinate {c!r}")
            if not math.isfinite(c):
                raise GeometryError(f"{label}: point {k} has a non-finite coordinate {c!r} "
                                    f"({_COORDINATE_RANGE})")
            if abs(c) > MAX_COORDINATE:
                raise GeometryError(f"{label}: point {k} has a coordinate of {c:g} m "
                                    f"({_COORDINATE_RANGE})")
        q = (float(p[0]), float(p[1]))
        if pts and q == pts[-1]:
            continue  # consecutive duplicate
        pts.append(q)
    if ring and len(pts) > 1 and pts[0] == pts[-1]:
        pts.pop()
    need = 3 if ring else 2
    if len(pts) == 1 and k > 0:
        what = "zero area" if ring else "zero length"
        raise GeometryError(f"{label}: all points coincide, so it has {what}")
    if len(pts) < need:
        what = "polygon" if ring else "line"
        raise GeometryError(
            f"{label}: a {what} needs at least {need} distinct points, got {len(pts)}"
        )
    return tuple(pts)


def _check_name(name: Any, kind: str) -> str:
    if not isinstance(name, str) or not name.strip():
        raise GeometryError(f"{kind} name must be a non-empty string, got {name!r} "
                            f"({type(name).__name__})")
    return name


def _collinear(points: Points) -> bool:
    """All points on one straight line (to round-off relative to the extent)."""
    p = np.asarray(points, float)
    d = p - p[0]
    far = d[np.argmax(np.hypot(d[:, 0], d[:, 1]))]
    scale = float(np.hypot(*far))
    if scale == 0.0:
        return True
    cross = far[0] * d[:, 1] - far[1] * d[:, 0]
    return bool(np.all(np.abs(cross) <= 1e-12 * scale * scale))


def _polygon(points: Points, label: str) -> Polygon:
    if _collinear(points):  # (a ring of them doubles back on itself: say what it is)
        raise GeometryError(f"{label}: all {len(points)} points lie on one straight line, so "
                            f"the polygon has zero area")
    ring = LinearRing(points)
    if not ring.is_simple:
        raise GeometryError(f"{label}: the outline intersects itself")
    poly = Polygon(points)
    if not poly.is_valid:
        reason = shapely.is_valid_reason(poly)
        raise GeometryError(f"{label}: invalid polygon ({reason})")
    if not poly.area > 0.0:
        raise GeometryError(f"{label}: the polygon has zero area")
    return poly


def _check_seed(seed: Any) -> None:
    """A one-line error unless ``seed`` (a room's or a building's) is None or a whole
    number from 0 to 2**32 - 1 (numpy's seeds)."""
    if seed is None:
        return
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2 ** 32:
        raise GeometryError(f"seed must be a whole number from 0 to 4294967295, got {seed!r}")


def _check_preset(preset: Any) -> None:
    """A one-line error unless ``preset`` (a room's or a building's) is None or a preset's
    name."""
    if preset is None:
        return
    from ..presets import PRESETS

    if not isinstance(preset, str) or preset not in PRESETS:
        raise GeometryError(f"unknown preset {preset!r} (presets: {', '.join(PRESETS)})")


def _positive(value: Any, what: str, label: str, *, integer: bool = False) -> float | int | None:
    if value is None:
        return None
    if not _is_real(value) or not math.isfinite(value) or value <= 0:
        raise GeometryError(f"{label}: {what} must be a positive finite number, got {value!r}")
    if integer:
        if int(value) != value:
            raise GeometryError(f"{label}: {what} must be a whole number, got {value!r}")
        return int(value)
    return float(value)


# --------------------------------------------------------------------------- elements
@dataclass(frozen=True)
class Obstacle:
    """A polygonal obstacle (a hole in the walkable area).

    Parameters
    ----------
    name
        Unique obstacle name.
    polygon
        Vertices [m] of the obstacle outline, in either orientation.
    """

    name: str
    polygon: Points

    def __post_init__(self) -> None:
        _check_name(self.name, "obstacle")
        label = f"obstacle '{self.name}'"
        object.__setattr__(self, "polygon", _coerce_points(self.polygon, label, ring=True))
        _polygon(self.polygon, label)

    @cached_property
    def shape(self) -> Polygon:
        """The obstacle as a shapely polygon [m]."""
        return Polygon(self.polygon)


@dataclass(frozen=True)
class Exit:
    """A named exit: a segment or polyline on the outline or on an obstacle's boundary.

    Parameters
    ----------
    name
        Unique exit name.
    polyline
        Vertices [m] of the exit, following the boundary.
    """

    name: str
    polyline: Points

    def __post_init__(self) -> None:
        _check_name(self.name, "exit")
        label = f"exit '{self.name}'"
        object.__setattr__(self, "polyline", _coerce_points(self.polyline, label, ring=False))
        line = LineString(self.polyline)
        if not line.length > 0:
            raise GeometryError(f"{label}: the exit has zero length")
        if not line.is_simple:
            raise GeometryError(f"{label}: the exit polyline overlaps itself")

    @cached_property
    def shape(self) -> LineString:
        """The exit as a shapely line string [m]."""
        return LineString(self.polyline)


#: lattice spacing [m] of an entrance's placeholder positions (:meth:`StartArea.positions`)
ENTRANCE_SPACING = 0.5

#: [ped/m^2] the densest crowd a start area may hold (by its spacing, density or count per
#: area): local densities of about 10 /m^2 were measured in the densest crowds (Helbing,
#: Johansson & Al-Abideen 2007), and the jam densities of the speed laws lie below
MAX_START_DENSITY = 10.0


@dataclass(frozen=True)
class StartArea:
    """A polygon filled with pedestrians at the start of a run.

    Exactly one of ``count``, ``spacing`` or ``density`` is given. Pedestrians are placed on a
    square lattice anchored at the polygon's lower-left bounding-box corner plus half a
    spacing (so the paper's 48 x 50 m block at 1 m spacing gives the 2400 points
    (i - 0.5, j - 0.5)); lattice points outside the polygon are dropped. A room requires its
    start areas to lie in the walkable area (not overlapping obstacles). ``density`` uses the
    spacing ``1/sqrt(density)``; ``count`` shrinks the spacing from ``sqrt(area/count)`` until
    enough points fit and keeps ``count`` of them, evenly spread over the lattice order.

    Parameters
    ----------
    name
        Unique start-area name.
    polygon
        Vertices [m] of the area.
    count
        Number of pedestrians.
    spacing
        Lattice spacing [m].
    density
        Pedestrian density [ped/m^2].
    premovement, speed, radius
        Optional distributions (:mod:`pedmesh.population`) of the premovement time [s]
        before a pedestrian starts walking, the free walking speed [m/s] and the body
        radius [m]: a number (constant) or a dict such as ``{"distribution": "normal",
        "mean": 1.34, "sd": 0.26, "min": 0.46, "max": 2.22}``, within the physical ranges of
        :data:`pedmesh.population.RANGES` (speed 0.1-5 m/s, radius 0.05-1 m, premovement
        0-3600 s).
    exits
        Optional exits this area's people head for: a list of exit names (the quickest
        of them) or ``{name: fraction}`` (fractions of the people, adding up to 1).
    arrivals
        Optional: the area is an entrance. Its people are not in the room at the start but
        enter it here, one at each arrival time (:class:`pedmesh.population.Arrivals`:
        ``{"rate": r, "start": t0}`` [1/s], [s] for ``count`` people, or ``{"times": [...]}``
        [s]), each on the free spot of the area farthest from everyone once there is room;
        the continuum models add them where the area is, at rest. Needs ``count`` (or
        ``times``) and no ``premovement``.
    """

    name: str
    polygon: Points
    count: int | None = None
    spacing: float | None = None
    density: float | None = None
    premovement: Any = None
    speed: Any = None
    radius: Any = None
    exits: Any = None
    arrivals: Any = None

    def __post_init__(self) -> None:
        _check_name(self.name, "start area")
        label = f"start area '{self.name}'"
        object.__setattr__(self, "polygon", _coerce_points(self.polygon, label, ring=True))
        _polygon(self.polygon, label)
        if self.arrivals is not None:
            if self.spacing is not None or self.density is not None:
                raise GeometryError(f"{label}: an entrance ('arrivals') takes 'count', not "
                                    f"'spacing' or 'density'")
            if self.premovement is not None:
                raise GeometryError(f"{label}: give either 'premovement' or 'arrivals' (people "
                                    f"who arrive walk at once)")
            from ..population import arrivals_from_spec

            count = (None if self.count is None
                     else _positive(self.count, "count", label, integer=True))
            arr = arrivals_from_spec(self.arrivals, count, label)
            object.__setattr__(self, "arrivals", arr)
            object.__setattr__(self, "count", arr.count)
        given = [k for k in ("count", "spacing", "density") if getattr(self, k) is not None]
        if len(given) != 1:
            raise GeometryError(
                f"{label}: give exactly one of 'count', 'spacing' or 'density' "
                f"(got {', '.join(given) or 'none'})"
            )
        object.__setattr__(self, "count", _positive(self.count, "count", label, integer=True))
        object.__setattr__(self, "spacing", _positive(self.spacing, "spacing", label))
        object.__setattr__(self, "density", _positive(self.density, "density", label))
        if self.arrivals is None:  # (an entrance's people arrive one by one)
            self._check_density(label)
        from ..population import (Distribution, check_range, distribution_from_spec,
                                  exit_choice_from_spec)

        for key, positive in (("premovement", False), ("speed", True), ("radius", True)):
            v = getattr(self, key)
            if v is not None and not isinstance(v, Distribution):
                v = distribution_from_spec(v, key, label, positive=positive)
                object.__setattr__(self, key, v)
            if v is not None:  # (a Distribution given as one is checked too)
                check_range(v, key, label)
        if self.exits is not None:
            object.__setattr__(self, "exits", exit_choice_from_spec(self.exits, label))

    def _check_density(self, label: str) -> None:
        """A one-line error for a crowd denser than :data:`MAX_START_DENSITY` (before any
        lattice is made: a spacing of 1e-4 m would ask for 1e8 points per m^2)."""
        top = MAX_START_DENSITY * (1.0 + 1e-9)  # (the limit itself passes, round-off aside)
        if self.spacing is not None and 1.0 / self.spacing**2 > top:
            raise GeometryError(
                f"{label}: a spacing of {self.spacing:g} m packs {1.0 / self.spacing**2:.3g} "
                f"people per m^2, more than the {MAX_START_DENSITY:g} /m^2 of the densest "
                f"crowds (the spacing must be at least {MAX_START_DENSITY ** -0.5:.3g} m)")
        if self.density is not None and self.density > top:
            raise GeometryError(f"{label}: a density of {self.density:g} /m^2 is more than the "
                                f"{MAX_START_DENSITY:g} /m^2 of the densest crowds")
        if self.count is not None and self.count > max(1.0, top * self.shape.area):
            # (one person may stand in an area of any size: the area marks the spot)
            raise GeometryError(
                f"{label}: {self.count} people in {self.shape.area:.3g} m^2 are "
                f"{self.count / self.shape.area:.4g} /m^2, more than the "
                f"{MAX_START_DENSITY:g} /m^2 of the densest crowds")

    @property
    def expected_count(self) -> float:
        """About how many people the area holds, without placing them [ped]: ``count``, else
        its area over spacing^2 or times the density (the lattice holds this many to within
        its boundary rows). Runs check a crowd's size with it before anything is
        allocated (:func:`pedmesh.run.driver.check_crowd`)."""
        if self.count is not None:
            return float(self.count)
        rho = self.density if self.density is not None else 1.0 / self.spacing**2
        return float(rho * self.shape.area)

    @cached_property
    def shape(self) -> Polygon:
        """The start area as a shapely polygon [m]."""
        return Polygon(self.polygon)

    def lattice(self, spacing: float, region: Polygon | None = None) -> np.ndarray:
        """Square-lattice points (k, 2) [m] with the given spacing inside the area. A lattice
        whose bounding box holds more than :data:`LATTICE_BLOCK` points is made block by
        block where the area is (:func:`_lattice_blocks`): the same points, in the same
        order, in memory that grows with the points inside, not with the bounding box."""
        poly = self.shape if region is None else self.shape.intersection(region)
        x0, y0, x1, y1 = self.shape.bounds
        ax = _Axis(x0 + 0.5 * spacing, x1, spacing)
        ay = _Axis(y0 + 0.5 * spacing, y1, spacing)
        if ax.n * ay.n > LATTICE_BLOCK:
            return _lattice_blocks(poly, ax, ay)
        xs = np.arange(x0 + 0.5 * spacing, x1, spacing)
        ys = np.arange(y0 + 0.5 * spacing, y1, spacing)
        # x runs slowest so that the paper's numbering 50 i + j is the array order
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        pts = np.column_stack([gx.ravel(), gy.ravel()])
        if len(pts) == 0:
            return pts
        inside = shapely.contains_xy(poly, pts[:, 0], pts[:, 1])
        return pts[inside]

    def positions(self, region: Polygon | None = None) -> np.ndarray:
        """Initial pedestrian positions (k, 2) [m], restricted to ``region`` if given. An
        entrance's people are not in the room at the start: their rows are the area's
        lattice points at ``ENTRANCE_SPACING`` repeated ``count`` times (placeholders; the
        social force model places each on a free spot when they arrive)."""
        if self.arrivals is not None:
            spots = self.lattice(ENTRANCE_SPACING, region)
            if len(spots) == 0:
                c = (self.shape if region is None else self.shape.intersection(region))
                p = c.representative_point()
                spots = np.array([[p.x, p.y]])
            return np.resize(spots, (self.count, 2))
        if self.spacing is not None:
            return self.lattice(self.spacing, region)
        if self.density is not None:
            return self.lattice(1.0 / math.sqrt(self.density), region)
        area = self.shape.area if region is None else self.shape.intersection(region).area
        spacing = math.sqrt(area / self.count)
        for _ in range(200):
            pts = self.lattice(spacing, region)
            if len(pts) >= self.count:
                idx = np.round(np.linspace(0, len(pts) - 1, self.count)).astype(np.int64)
                return pts[idx]
            spacing *= 0.98
        raise GeometryError(
            f"start area '{self.name}': cannot place {self.count} pedestrians in it"
        )


#: the most lattice points :meth:`StartArea.lattice` tests at once (about 40 MB of arrays):
#: a larger bounding box is split into blocks, and blocks the area does not reach are
#: skipped. (A thin diagonal strip 0.5 m wide and 14 km long holds 70,000 people at
#: 10 /m^2, within a run's crowd limit, but its bounding box 1e9 lattice points: 32 GB.)
LATTICE_BLOCK = 1 << 20


class _Axis:
    """The coordinates [m] ``np.arange(start, stop, step)`` makes, one index range at a time:
    element i is ``start + i * ((start + step) - start)`` (element 1: ``start + step``),
    as numpy fills it, so that the blocks of a lattice equal the whole lattice's points."""

    def __init__(self, start: float, stop: float, step: float) -> None:
        self.start, self.step = start, step
        self.delta = (start + step) - start
        self.n = max(0, math.ceil((stop - start) / step))

    def values(self, i0: int, i1: int) -> np.ndarray:
        v = self.start + np.arange(i0, i1, dtype=np.float64) * self.delta
        if i0 <= 1 < i1:
            v[1 - i0] = self.start + self.step
        return v

    def indices(self, lo: float, hi: float, i0: int, i1: int) -> tuple[int, int]:
        """The index range within [i0, i1) whose coordinates may lie in [lo, hi] (one index
        of margin either side for round-off)."""
        a = math.floor((lo - self.start) / self.delta) - 1
        b = math.ceil((hi - self.start) / self.delta) + 2
        return max(i0, a), min(i1, b)


def _lattice_blocks(poly, ax: _Axis, ay: _Axis) -> np.ndarray:
    """The lattice points (k, 2) [m] of axes ``ax`` x ``ay`` inside ``poly``, in the
    whole lattice's order (x slowest), made in blocks of at most :data:`LATTICE_BLOCK`
    points: a block is first shrunk to the bounding box of the part of ``poly`` in it
    (skipped if there is none), and split in two along its longer side while too large."""
    if poly.is_empty:
        return np.zeros((0, 2))
    shapely.prepare(poly)
    h = 0.5 * ax.step
    found_i, found_j, found = [], [], []
    todo = [(0, ax.n, 0, ay.n)]
    while todo:
        i0, i1, j0, j1 = todo.pop()
        xa, xb = ax.values(i0, i0 + 1)[0], ax.values(i1 - 1, i1)[0]
        ya, yb = ay.values(j0, j0 + 1)[0], ay.values(j1 - 1, j1)[0]
        part = shapely.clip_by_rect(poly, xa - h, ya - h, xb + h, yb + h)
        if part.is_empty:
            continue
        px0, py0, px1, py1 = part.bounds
        i0, i1 = ax.indices(px0, px1, i0, i1)
        j0, j1 = ay.indices(py0, py1, j0, j1)
        if i0 >= i1 or j0 >= j1:
            continue
        if (i1 - i0) * (j1 - j0) > LATTICE_BLOCK:
            if i1 - i0 >= j1 - j0:
                m = (i0 + i1) // 2
                todo += [(i0, m, j0, j1), (m, i1, j0, j1)]
            else:
                m = (j0 + j1) // 2
                todo += [(i0, i1, j0, m), (i0, i1, m, j1)]
            continue
        gi, gj = np.meshgrid(np.arange(i0, i1), np.arange(j0, j1), indexing="ij")
        gx, gy = np.meshgrid(ax.values(i0, i1), ay.values(j0, j1), indexing="ij")
        inside = shapely.contains_xy(poly, gx.ravel(), gy.ravel())
        found_i.append(gi.ravel()[inside])
        found_j.append(gj.ravel()[inside])
        found.append(np.column_stack([gx.ravel()[inside], gy.ravel()[inside]]))
    if not found:
        return np.zeros((0, 2))
    order = np.lexsort((np.concatenate(found_j), np.concatenate(found_i)))
    return np.concatenate(found)[order]


@dataclass(frozen=True)
class MeasurementLine:
    """A named measurement line (e.g. for flow counts) [m]."""

    name: str
    polyline: Points

    def __post_init__(self) -> None:
        _check_name(self.name, "measurement line")
        label = f"measurement line '{self.name}'"
        object.__setattr__(self, "polyline", _coerce_points(self.polyline, label, ring=False))
        if not LineString(self.polyline).length > 0:
            raise GeometryError(f"{label}: the line has zero length")

    @cached_property
    def shape(self) -> LineString:
        """The line as a shapely line string [m]."""
        return LineString(self.polyline)


@dataclass(frozen=True)
class MeasurementArea:
    """A named measurement area (e.g. for density) [m]."""

    name: str
    polygon: Points

    def __post_init__(self) -> None:
        _check_name(self.name, "measurement area")
        label = f"measurement area '{self.name}'"
        object.__setattr__(self, "polygon", _coerce_points(self.polygon, label, ring=True))
        _polygon(self.polygon, label)

    @cached_property
    def shape(self) -> Polygon:
        """The area as a shapely polygon [m]."""
        return Polygon(self.polygon)


def _coerce_elements(items: Any, cls: type, kind: str) -> tuple:
    if items is None:
        return ()
    if isinstance(items, (str, bytes, dict)) or not isinstance(items, Iterable):
        raise GeometryError(f"{kind}s must be a list, got {items!r}")
    out = []
    for it in items:
        if isinstance(it, cls):
            out.append(it)
        elif isinstance(it, dict):
            try:
                out.append(cls(**it))
            except TypeError as exc:
                raise GeometryError(f"{kind} {it.get('name', '?')!r}: {exc}") from None
        else:
            raise GeometryError(f"{kind} must be a {cls.__name__} or a dict, got {it!r}")
    names = [o.name for o in out]
    for n in names:
        if names.count(n) > 1:
            raise GeometryError(f"{kind} name '{n}' is used more than once")
    return tuple(out)


# --------------------------------------------------------------------------- room
@dataclass(frozen=True)
class BoundaryRing:
    """One closed boundary ring of the walkable area, with the exits lying on it.

    ``owner`` is -1 for the room outline and the obstacle index otherwise.
    """

    owner: int
    points: Points
    exits: tuple[int, ...]


@dataclass(frozen=True)
class Room:
    """A validated room: outline (walls), obstacles (holes), exits, start areas and
    measurement elements. Coordinates in metres.

    Parameters
    ----------
    outline
        Vertices [m] of the outer wall polygon.
    obstacles
        :class:`Obstacle` objects (or dicts with ``name``, ``polygon``).
    exits
        :class:`Exit` objects (or dicts with ``name``, ``polyline``).
    start_areas
        :class:`StartArea` objects (or dicts).
    measurement_lines, measurement_areas
        Optional measurement elements.
    name
        Room name.
    description
        Free text.
    preset
        The parameter preset runs of this room use unless told otherwise
        (:mod:`pedmesh.presets`; None: the default).
    seed
        The random seed of its particle model runs unless told otherwise (``--seed``,
        ``seed=``): which realisation of the start areas' draws and placement (None: the
        plain lattice, the draws with seed 0).
    exits_elsewhere
        Names of exits outside this room that its start areas' ``exits`` may name: on a
        level of a building, the other levels' exits (set by the building's loader; the
        :class:`~pedmesh.geometry.building.Building` checks they exist).

    Raises
    ------
    GeometryError
        If any rule in the module docstring is violated.
    """

    outline: Points
    obstacles: tuple[Obstacle, ...] = ()
    exits: tuple[Exit, ...] = ()
    start_areas: tuple[StartArea, ...] = ()
    measurement_lines: tuple[MeasurementLine, ...] = ()
    measurement_areas: tuple[MeasurementArea, ...] = ()
    name: str = "room"
    description: str = ""
    preset: str | None = None
    seed: int | None = None
    exits_elsewhere: tuple[str, ...] = field(default=(), repr=False, compare=False)
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "exits_elsewhere", tuple(self.exits_elsewhere))
        if not isinstance(self.name, str):
            raise GeometryError(f"room name must be a string, got {self.name!r} "
                                f"({type(self.name).__name__})")
        if not isinstance(self.description, str):
            raise GeometryError(f"room description must be a string, got {self.description!r}")
        _check_preset(self.preset)
        _check_seed(self.seed)
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731
        set_("outline", _coerce_points(self.outline, "room outline", ring=True))
        set_("obstacles", _coerce_elements(self.obstacles, Obstacle, "obstacle"))
        set_("exits", _coerce_elements(self.exits, Exit, "exit"))
        set_("start_areas", _coerce_elements(self.start_areas, StartArea, "start area"))
        set_(
            "measurement_lines",
            _coerce_elements(self.measurement_lines, MeasurementLine, "measurement line"),
        )
        set_(
            "measurement_areas",
            _coerce_elements(self.measurement_areas, MeasurementArea, "measurement area"),
        )
        names = {e.name for e in self.exits} | set(self.exits_elsewhere)
        for s in self.start_areas:
            for e, _ in s.exits or ():
                if e not in names:
                    where = "the building" if self.exits_elsewhere else "the room"
                    raise GeometryError(f"start area '{s.name}': 'exits' names '{e}', which is "
                                        f"not an exit of {where} (exits: "
                                        f"{', '.join(sorted(names))})")
        self._validate()

    def no_way_out(self) -> list[tuple[None, str, str]]:
        """(None, start area, why) of every start area whose people can never leave: all of
        them if the room has no exit (its walkable area is connected: obstacles lie inside
        and never touch). The same form as :meth:`Building.no_way_out
        <pedmesh.geometry.building.Building.no_way_out>`, whose first item is the level."""
        if self.exits:
            return []
        return [(None, a.name, "the room has no exit") for a in self.start_areas]

    # ------------------------------------------------------------------ validation
    def _validate(self) -> None:
        outer = _polygon(self.outline, "room outline")
        obstacles = [o.shape for o in self.obstacles]
        for o, shp in zip(self.obstacles, obstacles):
            if not outer.contains_properly(shp):
                if not outer.intersects(shp):
                    raise GeometryError(f"obstacle '{o.name}' lies outside the room outline")
                if outer.contains(shp):
                    raise GeometryError(
                        f"obstacle '{o.name}' touches the room outline "
                        "(make it part of the outline instead)"
                    )
                raise GeometryError(f"obstacle '{o.name}' crosses the room outline")
        if len(obstacles) > 1:
            tree = shapely.STRtree(obstacles)
            pairs = tree.query(obstacles, predicate="intersects")
            for i, j in sorted(zip(*pairs)):
                if i < j:
                    a, b = self.obstacles[i].name, self.obstacles[j].name
                    verb = "touches" if obstacles[i].touches(obstacles[j]) else "overlaps"
                    raise GeometryError(f"obstacle '{a}' {verb} obstacle '{b}'")
        walkable = Polygon(self.outline, [o.polygon for o in self.obstacles])
        self._cache["walkable"] = walkable
        self._cache["rings"] = self._place_exits()
        region = walkable.buffer(EXIT_TOLERANCE)
        for s in self.start_areas:
            if not region.covers(s.shape):
                for o, shp in zip(self.obstacles, obstacles):
                    if s.shape.intersection(shp).area > EXIT_TOLERANCE**2:
                        raise GeometryError(f"start area '{s.name}' overlaps obstacle '{o.name}'")
                raise GeometryError(f"start area '{s.name}' is not inside the room")
        for m in self.measurement_lines:
            if not region.covers(m.shape):
                raise GeometryError(f"measurement line '{m.name}' leaves the walkable area")
        for m in self.measurement_areas:
            if not region.covers(m.shape):
                raise GeometryError(f"measurement area '{m.name}' leaves the walkable area")

    def _place_exits(self) -> tuple[BoundaryRing, ...]:
        """Find the ring each exit lies on, check it, and insert its vertices into the rings."""
        rings: list[tuple[int, Points]] = [(-1, self.outline)]
        rings += [(k, o.polygon) for k, o in enumerate(self.obstacles)]
        ring_lines = [LinearRing(pts) for _, pts in rings]
        on_ring: dict[int, list[int]] = {i: [] for i in range(len(rings))}
        for j, ex in enumerate(self.exits):
            line = ex.shape
            dists = [_directed_distance(line, r) for r in ring_lines]
            best = int(np.argmin(dists))
            if dists[best] > EXIT_TOLERANCE:
                raise GeometryError(
                    f"exit '{ex.name}' does not lie on the room outline or an obstacle boundary "
                    f"(it is {dists[best]:.6g} m away; tolerance {EXIT_TOLERANCE:g} m)"
                )
            on_ring[best].append(j)
        snapped: dict[int, Points] = {}
        out = []
        for i, (owner, pts) in enumerate(rings):
            aug = list(pts)
            for j in on_ring[i]:
                new_line = []
                for p in self.exits[j].polyline:
                    aug, q = _insert_on_ring(aug, p)
                    new_line.append(q)
                snapped[j] = tuple(new_line)
            for a in range(len(on_ring[i])):
                for b in range(a + 1, len(on_ring[i])):
                    ja, jb = on_ring[i][a], on_ring[i][b]
                    inter = LineString(snapped[ja]).intersection(LineString(snapped[jb]))
                    if inter.length > EXIT_TOLERANCE:
                        raise GeometryError(
                            f"exit '{self.exits[ja].name}' overlaps exit '{self.exits[jb].name}'"
                        )
            out.append(BoundaryRing(owner=owner, points=tuple(aug), exits=tuple(on_ring[i])))
        self._cache["snapped_exits"] = tuple(snapped[j] for j in range(len(self.exits)))
        return tuple(out)

    # ------------------------------------------------------------------ derived
    @property
    def walkable(self) -> Polygon:
        """The walkable area (outline minus obstacles) as a shapely polygon [m]."""
        return self._cache["walkable"]

    @property
    def area(self) -> float:
        """Walkable area [m^2]."""
        return float(self.walkable.area)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of the outline [m]."""
        return tuple(float(v) for v in Polygon(self.outline).bounds)  # type: ignore[return-value]

    @property
    def boundary_rings(self) -> tuple[BoundaryRing, ...]:
        """Outline and obstacle rings with every exit vertex inserted as a ring vertex."""
        return self._cache["rings"]

    @property
    def exit_names(self) -> tuple[str, ...]:
        return tuple(e.name for e in self.exits)

    @property
    def obstacle_names(self) -> tuple[str, ...]:
        return tuple(o.name for o in self.obstacles)

    def exit_polyline(self, k: int) -> Points:
        """Exit ``k``'s vertices projected onto the boundary it lies on [m]."""
        return self._cache["snapped_exits"][k]

    def exit_length(self, k: int) -> float:
        """Length [m] of exit ``k`` along the boundary."""
        return float(LineString(self.exit_polyline(k)).length)

    def exit_index(self, name: str) -> int:
        """Index of the exit called ``name``."""
        for k, e in enumerate(self.exits):
            if e.name == name:
                return k
        raise GeometryError(f"room '{self.name}' has no exit '{name}' (exits: {self.exit_names})")

    def initial_positions(self) -> np.ndarray:
        """Pedestrian start positions (N, 2) [m] from all start areas, in area order."""
        parts = [s.positions(self.walkable) for s in self.start_areas]
        if not parts:
            return np.zeros((0, 2))
        return np.concatenate(parts, axis=0)

    def with_changes(self, **changes: Any) -> "Room":
        """A new (re-validated) room with some fields replaced."""
        import dataclasses

        return dataclasses.replace(self, **changes)


def _directed_distance(line: LineString, ring: LinearRing) -> float:
    """Largest distance [m] from a point of ``line`` to ``ring``."""
    if line.difference(ring.buffer(EXIT_TOLERANCE, quad_segs=16)).length == 0.0:
        return 0.0
    dense = shapely.segmentize(line, max(line.length / 256.0, 1e-9))
    return max(ring.distance(Point(p)) for p in dense.coords)


def _insert_on_ring(ring: list, p: tuple[float, float]) -> tuple[list, tuple[float, float]]:
    """Insert point ``p`` (within the tolerance of the ring) as a ring vertex.

    Returns the new ring and the vertex used (an existing vertex within the tolerance, or the
    projection of ``p`` onto its nearest ring segment).
    """
    P = np.asarray(ring, dtype=float)
    Q = np.roll(P, -1, axis=0)
    x = np.asarray(p, dtype=float)
    dv = np.hypot(*(P - x).T)
    k = int(np.argmin(dv))
    if dv[k] <= EXIT_TOLERANCE:
        return ring, tuple(ring[k])
    d = Q - P
    L2 = np.einsum("ij,ij->i", d, d)
    t = np.clip(np.einsum("ij,ij->i", x - P, d) / L2, 0.0, 1.0)
    foot = P + t[:, None] * d
    ds = np.hypot(*(foot - x).T)
    s = int(np.argmin(ds))
    # keep the given point if it is already on the segment to round-off
    cross = d[s, 0] * (x[1] - P[s, 1]) - d[s, 1] * (x[0] - P[s, 0])
    q = tuple(x) if abs(cross) <= 1e-13 * L2[s] else (float(foot[s, 0]), float(foot[s, 1]))
    q = (float(q[0]), float(q[1]))
    return ring[: s + 1] + [q] + ring[s + 1 :], q
