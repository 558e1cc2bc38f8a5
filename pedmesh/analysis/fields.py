"""Continuum fields of a particle crowd: the paper's kernel density and kernel velocity."""

from __future__ import annotations

import itertools
import math

import numpy as np

from ..parameters import DEFAULTS as D

__all__ = ["kernel_density", "kernel_velocity", "vertex_to_cell", "GridKernelDensity"]

#: kernel_density's cut-off in units of R
_DENSITY_CUTOFF = 3.0


def _pairs(positions, points, cutoff):
    """(pedestrian index, point index, distance) of all pairs closer than ``cutoff``, by
    point and then by pedestrian (the lists of a query of several points are sorted)."""
    from scipy.spatial import cKDTree

    # only the pedestrians within the cut-off of the points' bounding box go into the tree
    # (an exit's few points: a handful of the crowd); their indices keep their order, so
    # the lists are those of a tree of everyone
    points = np.asarray(points, float).reshape(-1, 2)
    if len(points) == 0 or len(positions) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    pad = cutoff * (1.0 + 1e-9) + 1e-12  # (a margin for the rounding of the box)
    lo = points.min(axis=0) - pad
    hi = points.max(axis=0) + pad
    near = np.flatnonzero((positions[:, 0] >= lo[0]) & (positions[:, 0] <= hi[0])
                          & (positions[:, 1] >= lo[1]) & (positions[:, 1] <= hi[1]))
    if len(near) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    lists = cKDTree(positions[near]).query_ball_point(points, cutoff)
    counts = np.fromiter(map(len, lists), np.int64, len(lists))
    col = np.repeat(np.arange(len(points)), counts)
    row = near[np.fromiter(itertools.chain.from_iterable(lists), np.int64, int(counts.sum()))]
    d = np.hypot(*(positions[row] - points[col]).T) if len(row) else np.zeros(0)
    return row, col, d


def _weights(d: np.ndarray, R: float) -> np.ndarray:
    """The kernel's weights ``exp(-(d / R)^2)`` of the distances ``d`` [m]."""
    return np.exp(-(d / R) ** 2)


def _density(n: int, col: np.ndarray, w: np.ndarray, R: float) -> np.ndarray:
    """Kernel density [ped/m^2] at ``n`` points from the weights ``w`` of their pairs."""
    out = np.zeros(n)
    np.add.at(out, col, w / (math.pi * R * R))
    return out


def _velocity(n: int, row: np.ndarray, col: np.ndarray, w: np.ndarray,
              vel: np.ndarray) -> np.ndarray:
    """Kernel-averaged velocity [m/s] at ``n`` points from the weights ``w`` of their pairs
    (zero where there are none)."""
    num = np.zeros((n, 2))
    den = np.zeros(n)
    np.add.at(den, col, w)
    np.add.at(num, col, w[:, None] * vel[row])
    out = np.zeros_like(num)
    ok = den > 0
    out[ok] = num[ok] / den[ok, None]
    return out


def kernel_density(*, positions: np.ndarray, points: np.ndarray, R: float = D['R'],
                   cutoff: float = _DENSITY_CUTOFF) -> np.ndarray:
    """Gaussian kernel density (paper eq3, eq4) [ped/m^2] of pedestrians at ``points``.

    ``rho(x) = sum_j exp(-|x_j - x|^2 / R^2) / (pi R^2)``, truncated at ``cutoff * R``
    (1.2e-4 of the kernel's mass lies beyond 3 R).

    Parameters
    ----------
    positions
        (N, 2) pedestrian positions [m].
    points
        (p, 2) evaluation points [m].
    R
        Kernel width [m].
    """
    pos = np.asarray(positions, float).reshape(-1, 2)
    pts = np.asarray(points, float).reshape(-1, 2)
    out = np.zeros(len(pts))
    if len(pos) == 0 or len(pts) == 0:
        return out
    row, col, d = _pairs(pos, pts, cutoff * R)
    return _density(len(pts), col, _weights(d, R), R)


def kernel_velocity(*, positions: np.ndarray, velocities: np.ndarray, points: np.ndarray,
                    R: float = D['R'],
                    cutoff: float = D['density_cutoff']) -> np.ndarray:
    """Kernel-averaged velocity (paper, outflow section) [m/s] at ``points``:
    ``u(x) = sum_j v_j w(|x_j - x|) / sum_j w(|x_j - x|)``; zero where no pedestrian is
    within the cut-off."""
    pos = np.asarray(positions, float).reshape(-1, 2)
    vel = np.asarray(velocities, float).reshape(-1, 2)
    pts = np.asarray(points, float).reshape(-1, 2)
    if not (len(pos) and len(pts)):
        return np.zeros((len(pts), 2))
    row, col, d = _pairs(pos, pts, cutoff * R)
    return _velocity(len(pts), row, col, _weights(d, R), vel)


def vertex_to_cell(*, mesh, values: np.ndarray) -> np.ndarray:
    """Cell values as the mean of the three vertex values."""
    v = np.asarray(values)
    return v[mesh.triangles].mean(axis=1)


#: :class:`GridKernelDensity`'s grid cell in units of the kernel width
GRID_CELL_PER_KERNEL = 0.25
#: ... and its largest number of grid nodes (the cell grows beyond that)
GRID_MAX_NODES = 4_000_000


def _apart(i0: np.ndarray, i1: np.ndarray, j0: np.ndarray, j1: np.ndarray,
           r: int) -> list[np.ndarray]:
    """Groups of the boxes ``[i0 - r, i1 + r] x [j0 - r, j1 + r]`` (k,) of grid nodes such
    that the boxes of two groups are more than a node apart (so that no node reads a node
    of another group's box, and no point's four nodes lie in two): split where the boxes
    sorted along one axis leave such a gap, then each part along the other axis, until no
    part splits. Returns the indices of each group."""
    out = []
    todo = [(np.arange(len(i0)), 0, True)]
    while todo:
        g, axis, split_other = todo.pop()
        lo, hi = (i0, i1) if axis == 0 else (j0, j1)
        order = g[np.argsort(lo[g], kind="stable")]
        reach = np.maximum.accumulate(hi[order])
        cut = np.flatnonzero(lo[order][1:] - reach[:-1] > 2 * r + 1) + 1
        if len(cut):
            for part in np.split(order, cut):
                todo.append((part, 1 - axis, True))
        elif split_other:
            todo.append((g, 1 - axis, False))
        else:
            out.append(np.sort(g))
    return out


class GridKernelDensity:
    """The Gaussian kernel density ``sum_j exp(-|x_j - x|^2 / L^2) / (pi L^2)`` [ped/m^2]
    of a crowd at fixed ``points`` [m], for kernels much wider than the people are apart
    (the route's crowd density, ``route_kernel``), where summing over pairs would cost
    hundreds of neighbours a point.

    The crowd is binned onto a grid of cell ``h`` = L / 4 [m] (each person's unit mass
    shared among the four nodes around them, bilinearly), smoothed by a Gaussian filter
    (:func:`scipy.ndimage.gaussian_filter`, nothing beyond the grid), and read at the
    points bilinearly. The two bilinear steps widen the kernel by a variance of ``h^2 / 6``
    each per axis, so the filter's is ``L^2 / 2 - h^2 / 3``: the result has the kernel's
    mass and variance, and its shape within a fraction of a per cent of the kernel's
    (tested against :func:`kernel_density`). The grid covers the points; people outside it
    are counted at its edge.
    """

    def __init__(self, points: np.ndarray, length: float) -> None:
        pts = np.asarray(points, float).reshape(-1, 2)
        if not (math.isfinite(length) and length > 0):
            raise ValueError(f"kernel width must be a positive number of metres, got {length!r}")
        if len(pts) == 0:
            raise ValueError("no points to evaluate the density at")
        self.length = float(length)
        lo = pts.min(axis=0)
        span = pts.max(axis=0) - lo
        h = GRID_CELL_PER_KERNEL * self.length
        h = max(h, math.sqrt(float((span[0] + 4 * h) * (span[1] + 4 * h)) / GRID_MAX_NODES))
        self.cell = h
        self.origin = lo - 2.0 * h
        self.shape = (int(math.ceil(span[0] / h)) + 5, int(math.ceil(span[1] / h)) + 5)
        self.sigma = math.sqrt(0.5 * self.length ** 2 - h * h / 3.0) / h  # [cells]
        self._idx, self._w = self._bilinear(pts)
        self.n_points = len(pts)

    def _bilinear(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(4, p) flat node indices and weights of the bilinear stencil of each point."""
        nx, ny = self.shape
        f = (xy - self.origin) / self.cell
        i = np.clip(np.floor(f[:, 0]).astype(np.int64), 0, nx - 2)
        j = np.clip(np.floor(f[:, 1]).astype(np.int64), 0, ny - 2)
        a = np.clip(f[:, 0] - i, 0.0, 1.0)
        b = np.clip(f[:, 1] - j, 0.0, 1.0)
        idx = np.stack([i * ny + j, (i + 1) * ny + j, i * ny + j + 1, (i + 1) * ny + j + 1])
        w = np.stack([(1 - a) * (1 - b), a * (1 - b), (1 - a) * b, a * b])
        return idx, w

    def grid(self, positions: np.ndarray) -> np.ndarray:
        """The smoothed density [ped/m^2] at the grid's nodes (``shape``; node (i, j) at
        ``origin + (i, j) cell``)."""
        from scipy import ndimage

        x = np.asarray(positions, float).reshape(-1, 2)
        idx, w = self._bilinear(x)
        nx, ny = self.shape
        mass = np.bincount(idx.ravel(), weights=w.ravel(), minlength=nx * ny)
        g = mass.reshape(nx, ny) / (self.cell * self.cell)
        return ndimage.gaussian_filter(g, self.sigma, mode="constant", cval=0.0,
                                       truncate=4.0)

    def __call__(self, positions: np.ndarray) -> np.ndarray:
        """(p,) the density [ped/m^2] at the points of a crowd at ``positions`` (N, 2) [m]."""
        if len(positions) == 0:
            return np.zeros(self.n_points)
        g = self.grid(positions).ravel()
        return np.einsum("kp,kp->p", g[self._idx], self._w)

    def near(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(points, density)``: the points (indices) where the density of a crowd at
        ``positions`` may be above 0 and the density there, the same numbers as
        :meth:`__call__`'s, which is 0 at every other point; the work grows with the
        crowd's extent, not with the grid's. The filter reaches ``r`` nodes
        (:func:`scipy.ndimage.gaussian_filter`'s radius) along each axis, so only the
        nodes within ``r`` of a person's nodes get density, and those have the full grid's:
        each node's sum reads the same nodes, zero beyond. The crowd is taken in groups
        whose boxes (their nodes and ``r`` more about them) lie apart, one box each (e.g.
        one for each floor people stand on)."""
        x = np.asarray(positions, float).reshape(-1, 2)
        if len(x) == 0:
            return np.zeros(0, np.int64), np.zeros(0)
        ny = self.shape[1]
        r = int(4.0 * self.sigma + 0.5)  # (truncate 4, as in grid())
        idx, w = self._bilinear(x)
        i, j = idx // ny, idx % ny
        parts = [self._near_box(idx[:, g], w[:, g], r) for g in
                 _apart(i.min(axis=0), i.max(axis=0), j.min(axis=0), j.max(axis=0), r)]
        return (np.concatenate([p for p, _ in parts]),
                np.concatenate([v for _, v in parts]))

    def _near_box(self, idx: np.ndarray, w: np.ndarray, r: int):
        """:meth:`near` for the people with stencils ``idx``, ``w`` (4, k), alone in their
        box."""
        from scipy import ndimage

        from ..mesh.triangle_mesh import csr_ranges

        nx, ny = self.shape
        none = (np.zeros(0, np.int64), np.zeros(0))
        i, j = idx // ny, idx % ny
        i0, i1 = max(int(i.min()) - r, 0), min(int(i.max()) + r, nx - 1)
        j0, j1 = max(int(j.min()) - r, 0), min(int(j.max()) + r, ny - 1)
        wy = j1 - j0 + 1
        local = (i - i0) * wy + (j - j0)
        mass = np.bincount(local.ravel(), weights=w.ravel(), minlength=(i1 - i0 + 1) * wy)
        g = mass.reshape(i1 - i0 + 1, wy) / (self.cell * self.cell)
        g = ndimage.gaussian_filter(g, self.sigma, mode="constant", cval=0.0, truncate=4.0)
        # the points whose stencil (lower-left node (a, b), a in [i0 - 1, i1], b likewise)
        # reaches the box
        ptr, order = self._by_node()
        a = np.arange(max(i0 - 1, 0), min(i1, nx - 2) + 1)
        b0, b1 = max(j0 - 1, 0), min(j1, ny - 2)
        if len(a) == 0 or b1 < b0:
            return none
        lo, hi = ptr[a * ny + b0], ptr[a * ny + b1 + 1]
        pts = order[csr_ranges(lo, hi - lo)]
        if len(pts) == 0:
            return none
        k = self._idx[:, pts]
        ki, kj = k // ny, k % ny
        inside = (ki >= i0) & (ki <= i1) & (kj >= j0) & (kj <= j1)
        gv = np.append(g.ravel(), 0.0)
        vals = gv[np.where(inside, (ki - i0) * wy + (kj - j0), gv.size - 1)]
        w_p = self._w[:, pts]
        # einsum's sum over k is in k's order on C-ordered (4, p) arrays of p > 1 points
        # (as in __call__); on others (one point, or the F order a fancy index along the
        # second axis gives) it may group the terms otherwise
        reps = 2 if len(pts) == 1 else 1
        vals = np.ascontiguousarray(np.repeat(vals, reps, axis=1))
        w_p = np.ascontiguousarray(np.repeat(w_p, reps, axis=1))
        return pts, np.einsum("kp,kp->p", vals, w_p)[:len(pts)]

    def _by_node(self) -> tuple[np.ndarray, np.ndarray]:
        """The points by the lower-left node of their stencil: CSR ``(ptr, points)``."""
        if not hasattr(self, "_node_csr"):
            key = self._idx[0]
            order = np.argsort(key, kind="stable")
            ptr = np.zeros(self.shape[0] * self.shape[1] + 1, np.int64)
            np.cumsum(np.bincount(key, minlength=self.shape[0] * self.shape[1]), out=ptr[1:])
            self._node_csr = (ptr, order)
        return self._node_csr
