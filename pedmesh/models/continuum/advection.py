"""Linear advection ``q_t + div(q a) = 0`` with a constant velocity ``a``: a verification
model (exact solutions are translations), not a pedestrian model."""

from __future__ import annotations

import numpy as np

from .base import MacroModel

__all__ = ["Advection"]


class Advection(MacroModel):
    name = "advection"
    n_vars = 1
    exit_conditions = ("vacuum", "transmissive")
    needs_route = False
    direction_dependent_flux = False

    def __init__(self, ax: float = 1.0, ay: float = 0.0) -> None:
        self.a = np.array([float(ax), float(ay)])

    def flux(self, qL, qR, nx, ny, ex, ey):
        an = self.a[0] * nx + self.a[1] * ny
        F = (0.5 * (qL[:, 0] + qR[:, 0]) * an - 0.5 * np.abs(an) * (qR[:, 0] - qL[:, 0]))[:, None]
        return F, np.abs(an)

    def wall_flux(self, q, nx, ny, ex, ey):
        return np.zeros_like(q)

    def exit_flux(self, q, nx, ny, ex, ey, kind):
        an = self.a[0] * nx + self.a[1] * ny
        return (q[:, 0] * np.maximum(an, 0.0))[:, None]

    def velocity(self, q):
        return np.broadcast_to(self.a, (len(q), 2)).copy()

