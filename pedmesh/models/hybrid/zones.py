"""Where the hybrid model's agents live: a set of the mesh's triangles.

A triangle belongs to the agent zone when its centroid lies in one of the given polygons
[m] (a room file's fixed zones) or within ``near_exits`` [m] of an exit (where the crowd
is densest and the continuum's law is least sure, docs/validation/dense_crowds.md).

:class:`DensityTrigger` moves cells in and out as the run goes, on top of that fixed part:
a cell joins the agents where the crowd reaches ``rho_on`` and leaves where it has thinned
below ``rho_off`` < ``rho_on`` (hysteresis), and never sooner than ``dwell`` seconds after
its last switch, so that a crowd passing over a cell switches it twice (in and out), not
at every flicker of its density about a threshold. (Not yet used by the coupled run.)
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from ...errors import ParameterError
from ...mesh.triangle_mesh import TriMesh

__all__ = ["DensityTrigger", "zone_cells"]


def zone_cells(mesh: TriMesh, polygons: Iterable[Sequence[Sequence[float]]] = (), *,
               near_exits: float = 0.0) -> np.ndarray:
    """(m,) bool: the triangles of ``mesh`` in the agent zone, those whose centroid lies
    inside (or on) one of ``polygons`` (each a sequence of (x, y) [m], at least three
    points) or within ``near_exits`` [m] of an exit edge (0: none)."""
    import shapely

    if not (np.isfinite(near_exits) and near_exits >= 0):
        raise ParameterError(f"near_exits must be a distance >= 0 [m], got {near_exits!r}")
    c = mesh.centroids
    inside = np.zeros(mesh.n_triangles, bool)
    for k, poly in enumerate(polygons):
        pts = np.asarray(poly, float)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 3 or not np.all(np.isfinite(pts)):
            raise ParameterError(f"agent zone {k}: a polygon needs at least three finite "
                                 f"(x, y) points [m], got shape {pts.shape}")
        shape = shapely.Polygon(pts)
        if not shape.is_valid or shape.area <= 0:
            raise ParameterError(f"agent zone {k}: the polygon is not a simple polygon with "
                                 "an area (self-crossing or degenerate)")
        inside |= shapely.intersects_xy(shape, c[:, 0], c[:, 1])
    if near_exits > 0:
        e = mesh.exit_edges()
        if len(e):
            p = mesh.points[mesh.edges[e]]  # (k, 2, 2)
            lines = shapely.multilinestrings(list(p))
            inside |= shapely.dwithin(lines, shapely.points(c), near_exits)
    return inside


class DensityTrigger:
    """The agent zone as the run goes: the cells ``fixed`` ((m,) bool: the room's zones,
    :func:`zone_cells`) always, and the others while their crowd is dense (see the module
    docstring).

    ``rho_on`` [ped/m^2]: a cell outside the zone joins it at this density or above;
    ``rho_off`` [ped/m^2] (below ``rho_on``): a cell of the zone that is not fixed leaves
    it below this density; ``dwell`` [s]: the least time between two switches of a cell.
    :attr:`zone` is the current zone, :attr:`switches` how often each cell switched."""

    def __init__(self, fixed: np.ndarray, *, rho_on: float, rho_off: float,
                 dwell: float) -> None:
        for name, v in (("rho_on", rho_on), ("rho_off", rho_off)):
            if not (np.isfinite(v) and v > 0):
                raise ParameterError(f"{name} must be a density > 0 [ped/m^2], got {v!r}")
        if not rho_off < rho_on:
            raise ParameterError(f"rho_off ({rho_off:g} ped/m^2) must be below rho_on "
                                 f"({rho_on:g} ped/m^2): the gap between them keeps a cell "
                                 "from switching at every flicker of its density")
        if not (np.isfinite(dwell) and dwell >= 0):
            raise ParameterError(f"dwell must be a time >= 0 [s], got {dwell!r}")
        self.fixed = np.asarray(fixed, bool).ravel().copy()
        self.rho_on, self.rho_off, self.dwell = float(rho_on), float(rho_off), float(dwell)
        self.zone = self.fixed.copy()
        self.switches = np.zeros(len(self.fixed), np.int64)
        self._since = np.full(len(self.fixed), -np.inf)  # [s] each cell's last switch

    def update(self, rho: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The zone after the cells' densities ``rho`` ((m,) [ped/m^2]: the crowd of both
        models) at time ``t`` [s]: the cells that joined and the cells that left (index
        arrays; :attr:`zone` is updated)."""
        rho = np.asarray(rho, float).ravel()
        if rho.shape != self.zone.shape:
            raise ParameterError(f"{len(rho)} densities for {len(self.zone)} cells")
        ready = t - self._since >= self.dwell
        join = np.flatnonzero(~self.zone & ready & (rho >= self.rho_on))
        leave = np.flatnonzero(self.zone & ~self.fixed & ready & (rho < self.rho_off))
        self.zone[join] = True
        self.zone[leave] = False
        changed = np.concatenate([join, leave])
        self._since[changed] = t
        self.switches[changed] += 1
        return join, leave
