"""RDUE / Hughes: ``rho_t + div(rho U_e(rho) e) = 0`` with ``U_e = U_f exp(-beta rho)`` and e
from the eikonal equation with cost 1/U_e(rho) (reactive dynamic user equilibrium).

Flux at a point with normal n: ``f(rho) (e.n)``, ``f(rho) = rho U_f exp(-beta rho)``;
Rusanov with ``alpha = max |f'(rho)| |e.n|``, ``f'(rho) = U_f (1 - beta rho) exp(-beta rho)``.
Walls pass nothing. Exits (default ``demand``): the Godunov flux into empty space,
``f(min(rho, rho*)) (e.n)_+`` with ``rho* = 1/beta``, so a saturated exit of width w passes
its capacity ``w U_f / (e beta)``; ``vacuum`` (Rusanov against 0) and ``transmissive``
(``f(rho) (e.n)_+``) are the alternatives.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ...errors import ParameterError
from .._kernels import FAST
from .base import MacroModel, register_macro_model

__all__ = ["RDUE"]


@nb.njit(**FAST)
def _rusanov(qL, qR, en, U_f, beta, F, alpha):
    for k in range(qL.shape[0]):
        rl = max(qL[k, 0], 0.0)
        rr = max(qR[k, 0], 0.0)
        el = math.exp(-beta * rl)
        er = math.exp(-beta * rr)
        fl = rl * U_f * el
        fr = rr * U_f * er
        a = max(abs(U_f * (1 - beta * rl) * el), abs(U_f * (1 - beta * rr) * er)) * abs(en[k])
        alpha[k] = a
        F[k, 0] = 0.5 * (fl + fr) * en[k] - 0.5 * a * (rr - rl)


class RDUE(MacroModel):
    """RDUE / Hughes model (see module docstring)."""

    name = "rdue"
    n_vars = 1
    exit_conditions = ("demand", "vacuum", "transmissive")

    def __init__(self, *, U_f: float = 1.034, beta: float = 0.05) -> None:
        for k, v in (("U_f", U_f), ("beta", beta)):
            if not (np.isfinite(v) and v > 0):
                raise ParameterError(f"parameter '{k}' must be positive, got {v!r}")
        self.U_f, self.beta = float(U_f), float(beta)

    def f(self, rho):
        return rho * self.U_f * np.exp(-self.beta * rho)

    def flux(self, qL, qR, nx, ny, ex, ey):
        F = np.empty_like(qL)
        a = np.empty(len(qL))
        _rusanov(qL, qR, ex * nx + ey * ny, self.U_f, self.beta, F, a)
        return F, a

    def wall_flux(self, q, nx, ny, ex, ey):
        return np.zeros_like(q)

    def exit_flux(self, q, nx, ny, ex, ey, kind):
        en = ex * nx + ey * ny
        r = np.maximum(q[:, 0], 0.0)
        if kind == "demand":
            return (self.f(np.minimum(r, 1.0 / self.beta)) * np.maximum(en, 0.0))[:, None]
        if kind == "transmissive":
            return (self.f(r) * np.maximum(en, 0.0))[:, None]
        if kind == "vacuum":
            F, _ = self.flux(q, np.zeros_like(q), nx, ny, ex, ey)
            return F
        raise ParameterError(f"unknown exit condition '{kind}'")

    def velocity(self, q):
        return np.zeros((len(q), 2))  # filled by the solver from U_e e

    def parameters(self) -> dict:
        return {"U_f": self.U_f, "beta": self.beta}


register_macro_model("rdue", RDUE)
