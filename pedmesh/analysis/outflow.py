"""Exit outflow: f_c(t) = integral over an exit of rho u.n ds (paper, outflow section)."""

from __future__ import annotations

import numpy as np

from .fields import _DENSITY_CUTOFF, _density, _pairs, _velocity, _weights
from ..parameters import DEFAULTS as D

__all__ = ["exit_gauss_points", "continuum_outflow", "particle_outflow", "crossing_rate"]

_S = (0.5 - np.sqrt(3) / 6, 0.5 + np.sqrt(3) / 6)


def exit_gauss_points(*, mesh, exit: int):
    """Gauss points (2 per edge), weights [m] and outward normals of an exit's edges."""
    e = mesh.exit_edges(exit)
    p0 = mesh.points[mesh.edges[e, 0]]
    p1 = mesh.points[mesh.edges[e, 1]]
    pts = np.concatenate([p0 + s * (p1 - p0) for s in _S])
    w = np.tile(0.5 * mesh.edge_lengths[e], 2)
    n = np.tile(mesh.edge_normals[e], (2, 1))
    tri = np.tile(mesh.edge_triangles[e, 0], 2)
    return pts, w, n, tri


def continuum_outflow(*, mesh, rho: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """Outflow [ped/s] through each exit from cell densities [ped/m^2] and cell velocities
    [m/s] (the values of the cells on the exit edges)."""
    out = np.zeros(len(mesh.exit_names))
    for k in range(len(out)):
        pts, w, n, tri = exit_gauss_points(mesh=mesh, exit=k)
        out[k] = np.sum(w * rho[tri] * np.einsum("ij,ij->i", velocity[tri], n))
    return out


def particle_outflow(*, mesh, positions: np.ndarray, velocities: np.ndarray,
                     R: float = D['R']) -> np.ndarray:
    """Outflow [ped/s] through each exit of a particle crowd, from the kernel density and the
    kernel-averaged velocity at the exit (the paper's definition for the particle model)."""
    out = np.zeros(len(mesh.exit_names))
    pos = np.asarray(positions, float).reshape(-1, 2)
    vel = np.asarray(velocities, float).reshape(-1, 2)
    for k in range(len(out)):
        pts, w, n, _ = exit_gauss_points(mesh=mesh, exit=k)
        if len(pos) == 0 or len(pts) == 0:
            rho, u = np.zeros(len(pts)), np.zeros((len(pts), 2))
        else:  # kernel_density and kernel_velocity at the exit's points, from one
            # neighbour search and one set of weights where their cut-offs are the same
            row, col, d = _pairs(pos, pts, _DENSITY_CUTOFF * R)
            kw = _weights(d, R)
            rho = _density(len(pts), col, kw, R)
            if D['density_cutoff'] != _DENSITY_CUTOFF:
                row, col, d = _pairs(pos, pts, D['density_cutoff'] * R)
                kw = _weights(d, R)
            u = _velocity(len(pts), row, col, kw, vel)
        out[k] = np.sum(w * rho * np.einsum("ij,ij->i", u, n))
    return out


def crossing_rate(*, exit_times: np.ndarray, t: np.ndarray, window: float = 2.0) -> np.ndarray:
    """Plain crossing rate [ped/s] at times ``t``: pedestrians who left in the window
    ``(t - window/2, t + window/2]`` divided by its length."""
    et = np.sort(np.asarray(exit_times, float)[np.isfinite(exit_times)])
    t = np.asarray(t, float)
    hi = np.searchsorted(et, t + 0.5 * window, side="right")
    lo = np.searchsorted(et, t - 0.5 * window, side="right")
    return (hi - lo) / window
