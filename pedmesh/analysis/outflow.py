"""Exit outflow: f_c(t) = integral over an exit of rho u.n ds (paper, outflow section)."""

from __future__ import annotations

import numpy as np

from .fields import _DENSITY_CUTOFF, _density, _pairs, _velocity, _weights
from ..parameters import DEFAULTS as D

__all__ = ["exit_gauss_points", "continuum_outflow", "particle_outflow", "crossing_rate"]

_S = (0.5 - np.sqrt(3) / 6, 0.5 + np.sqrt(3) / 6)


def _kept(mesh, key, make):
    """``make()``, kept in the mesh's cache under ``key`` (a mesh without one: made anew)."""
    cache = getattr(mesh, "_cache", None)
    if not isinstance(cache, dict):
        return make()
    if key not in cache:
        cache[key] = make()
    return cache[key]


def exit_gauss_points(*, mesh, exit: int):
    """Gauss points (2 per edge), weights [m] and outward normals of an exit's edges (kept
    in the mesh: read-only arrays)."""

    def make():
        e = mesh.exit_edges(exit)
        p0 = mesh.points[mesh.edges[e, 0]]
        p1 = mesh.points[mesh.edges[e, 1]]
        out = (np.concatenate([p0 + s * (p1 - p0) for s in _S]),
               np.tile(0.5 * mesh.edge_lengths[e], 2), np.tile(mesh.edge_normals[e], (2, 1)),
               np.tile(mesh.edge_triangles[e, 0], 2))
        for a in out:
            a.setflags(write=False)
        return out

    return _kept(mesh, ("exit_gauss_points", int(exit)), make)


def _all_exit_points(mesh):
    """Every exit's Gauss points, weights and normals concatenated, with the offsets of each
    exit's share (kept in the mesh)."""

    def make():
        parts = [exit_gauss_points(mesh=mesh, exit=k) for k in range(len(mesh.exit_names))]
        offsets = np.cumsum([0] + [len(p[1]) for p in parts]).astype(np.int64)
        return (np.concatenate([np.zeros((0, 2))] + [p[0] for p in parts]),
                np.concatenate([np.zeros(0)] + [p[1] for p in parts]),
                np.concatenate([np.zeros((0, 2))] + [p[2] for p in parts]), offsets)

    return _kept(mesh, "exit_gauss_all", make)


def continuum_outflow(*, mesh, rho: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """Outflow [ped/s] through each exit from cell densities [ped/m^2] and cell velocities
    [m/s] (the values of the cells on the exit edges)."""
    out = np.zeros(len(mesh.exit_names))
    for k in range(len(out)):
        pts, w, n, tri = exit_gauss_points(mesh=mesh, exit=k)
        out[k] = np.sum(w * rho[tri] * np.einsum("ij,ij->i", velocity[tri], n))
    return out


def particle_outflow(*, mesh, positions: np.ndarray, velocities: np.ndarray,
                     R: float = D['R'], n_exits: int | None = None) -> np.ndarray:
    """Outflow [ped/s] through each exit of a particle crowd, from the kernel density and the
    kernel-averaged velocity at the exit (the paper's definition for the particle model);
    with ``n_exits``, through the mesh's first ``n_exits`` exits only (a building's atlas
    has its stair edges as further exits)."""
    n_all = len(mesh.exit_names)
    out = np.zeros(n_all if n_exits is None else min(int(n_exits), n_all))
    pos = np.asarray(positions, float).reshape(-1, 2)
    vel = np.asarray(velocities, float).reshape(-1, 2)
    pts, w, n, offsets = _all_exit_points(mesh)
    m = offsets[len(out)]
    pts, w, n = pts[:m], w[:m], n[:m]
    if len(pos) == 0 or len(pts) == 0:
        return out
    # every exit's points in one neighbour search: each point's neighbours, and the order
    # they are summed in, are those of a search of its own exit's points
    row, col, d = _pairs(pos, pts, _DENSITY_CUTOFF * R)
    kw = _weights(d, R)
    rho = _density(len(pts), col, kw, R)
    if D['density_cutoff'] != _DENSITY_CUTOFF:
        row, col, d = _pairs(pos, pts, D['density_cutoff'] * R)
        kw = _weights(d, R)
    u = _velocity(len(pts), row, col, kw, vel)
    f = w * rho * np.einsum("ij,ij->i", u, n)
    for k in range(len(out)):
        out[k] = np.sum(f[offsets[k]:offsets[k + 1]])
    return out


def crossing_rate(*, exit_times: np.ndarray, t: np.ndarray, window: float = 2.0) -> np.ndarray:
    """Plain crossing rate [ped/s] at times ``t``: pedestrians who left in the window
    ``(t - window/2, t + window/2]`` divided by its length."""
    et = np.sort(np.asarray(exit_times, float)[np.isfinite(exit_times)])
    t = np.asarray(t, float)
    hi = np.searchsorted(et, t + 0.5 * window, side="right")
    lo = np.searchsorted(et, t - 0.5 * window, side="right")
    return (hi - lo) / window
