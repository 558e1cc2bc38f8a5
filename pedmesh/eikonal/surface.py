"""Fast marching on a building's surface (:class:`~pedmesh.mesh.surface.SurfaceMesh`).

The same compiled march as on a room (:mod:`pedmesh.eikonal.fmm_kernels`), on the surface's
3-D vertices: every triangle is planar, so its update in 3-D is the update in its own
chart, and a distance along a stair is measured on the slope. What needs the plane is done
piece by piece in each piece's chart: the obtuse-angle splits (their walk stops at a stair
edge, where the plain update takes over) and the straight rays from exit end points and
reflex corners (visible within the piece).

``cost`` [s/m] is per vertex or per triangle as on a room; :func:`stair_costs` gives the
cost of walking at the level speed and at the stairs' speeds up or down.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..errors import ParameterError
from ..mesh.surface import SurfaceMesh
from . import fmm_kernels as _fmm
from .fmm import (DEFAULT_CORNER_RADIUS, MAX_SPLIT_STEPS, EikonalSolver, _corner_rays, _csr,
                  _ray_samples)

__all__ = ["SurfaceEikonalSolver", "stair_costs", "surface_gradient"]


class SurfaceEikonalSolver(EikonalSolver):
    """:class:`~pedmesh.eikonal.EikonalSolver` on a building's surface mesh (see the
    module docstring); ``solve`` is the room solver's."""

    def __init__(self, surface: SurfaceMesh, exits: Sequence[str | int] | None = None,
                 corner_radius: float = DEFAULT_CORNER_RADIUS) -> None:
        if not isinstance(surface, SurfaceMesh):
            raise ParameterError("SurfaceEikonalSolver takes a building's SurfaceMesh")
        super().__init__(surface, exits, corner_radius)

    def _split_vertices(self) -> np.ndarray:
        """The obtuse-angle splits, piece by piece in each chart (a walk stops at a stair
        edge, the boundary of its piece), in surface numbering."""
        s = self.mesh
        split = np.full((s.n_triangles, 3), -1, np.int64)
        for p in s.pieces:
            m = p.mesh
            loc = _fmm.find_split_vertices(m.points, m.triangles, m.triangle_neighbors,
                                           MAX_SPLIT_STEPS)
            split[p.triangles] = np.where(loc >= 0, p.vertices[np.maximum(loc, 0)], loc)
        return split

    def _march_points(self) -> np.ndarray:
        return np.ascontiguousarray(self.mesh.points)

    def _rays(self) -> None:
        """The corner rays of every piece, in surface numbering (CSR by source vertex)."""
        s = self.mesh
        src, dst, length, samp_n, samp_tri = [], [], [], [], []
        for p in s.pieces:
            ptr, idx, ln = _corner_rays(p.mesh, self.corner_radius)
            if len(idx) == 0:
                continue
            sptr, stri = _ray_samples(p.mesh, ptr, idx, ln)
            src.append(p.vertices[np.repeat(np.arange(p.mesh.n_points), np.diff(ptr))])
            dst.append(p.vertices[idx])
            length.append(ln)
            samp_n.append(np.diff(sptr))
            samp_tri.append(np.split(p.triangles[stri], sptr[1:-1]))
        n = s.n_points
        if not src:
            self.ray_ptr = np.zeros(n + 1, np.int64)
            self.ray_idx = np.zeros(0, np.int32)
            self.ray_len = np.zeros(0)
            self.ray_samp_ptr, self.ray_samp_tri = np.zeros(1, np.int64), np.zeros(0, np.int64)
            return
        src = np.concatenate(src)
        self.ray_ptr, order = _csr(src, n)
        self.ray_idx = np.ascontiguousarray(np.concatenate(dst)[order], dtype=np.int32)
        self.ray_len = np.ascontiguousarray(np.concatenate(length)[order])
        samples = [x for part in samp_tri for x in part]
        samples = [samples[k] for k in order]
        counts = np.array([len(x) for x in samples], np.int64)
        self.ray_samp_ptr = np.zeros(len(samples) + 1, np.int64)
        np.cumsum(counts, out=self.ray_samp_ptr[1:])
        self.ray_samp_tri = np.concatenate(samples).astype(np.int64)


def stair_costs(surface: SurfaceMesh, phi: np.ndarray | None = None, *,
                level_cost: float | np.ndarray = 1.0) -> np.ndarray:
    """The cost [s/m] per triangle of walking on the surface: ``level_cost`` on the levels
    (a scalar or one value per triangle) and on a stair ``level_cost / speed_up`` going up,
    ``/ speed_down`` going down. Which way a stair is walked is read from the gradient of
    ``phi`` (a potential, e.g. the distance to the exits, decreasing towards them) along
    the stair's slope; without ``phi`` everyone goes down (the exits below)."""
    b = surface.building
    base = np.broadcast_to(np.asarray(level_cost, float), (surface.n_triangles,)).copy()
    for k, p in enumerate(surface.pieces):
        if p.kind != "stair":
            continue
        st = next(x for x in b.stairs if x.name == p.name)
        tris = p.triangles
        if phi is None or b.rise(st) == 0:
            down = np.ones(len(tris), bool)
        else:
            pts = surface.points[surface.triangles[tris]]  # (k, 3, 3)
            dz = pts[:, :, 2] - pts[:, :, 2].mean(axis=1)[:, None]
            dphi = phi[surface.triangles[tris]] - phi[surface.triangles[tris]].mean(axis=1)[
                :, None]
            # phi falls towards the exits: walking down the stair where phi grows with z
            down = np.sum(dz * dphi, axis=1) >= 0.0
        base[tris] = np.where(down, base[tris] / st.speed_down, base[tris] / st.speed_up)
    return base


def surface_gradient(surface: SurfaceMesh, phi: np.ndarray) -> np.ndarray:
    """The gradient (m, 3) of the piecewise-linear ``phi`` in each triangle's plane (tangent
    to the surface): ``-gradient / |gradient|`` is the walking direction."""
    p = surface.points[surface.triangles]  # (m, 3, 3)
    f = np.asarray(phi, float)[surface.triangles]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    d1, d2 = f[:, 1] - f[:, 0], f[:, 2] - f[:, 0]
    # g = a e1 + b e2 with g.e1 = d1, g.e2 = d2 (the Gram system of the triangle)
    g11 = np.sum(e1 * e1, axis=1)
    g12 = np.sum(e1 * e2, axis=1)
    g22 = np.sum(e2 * e2, axis=1)
    det = g11 * g22 - g12 * g12
    a = (d1 * g22 - d2 * g12) / det
    b = (d2 * g11 - d1 * g12) / det
    return a[:, None] * e1 + b[:, None] * e2
