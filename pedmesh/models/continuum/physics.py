"""Interaction kernels of the derived continuum models (paper eq. mac1, mac2).

* :class:`SFMRepulsion`: ``Phi(d) = (A exp((r_ij - d)/B) + k (r_ij - d)_+)/m`` [m/s^2 per
  ped/m^2 ... i.e. acceleration per unit density and area], the social force per unit mass;
* :class:`SFMFriction`: ``Psi(d) = kappa (r_ij - d)_+/m`` [1/s per ped/m^2 ...];
* :class:`LongRange`: the paper's weak-interaction illustration
  ``phi = psi = strength / (1 + (d/length)^2)``.

``gamma1 = pi int phi(r) r^2 dr`` and ``gamma2 = pi int psi(r) r dr`` are computed by
quadrature for any kernel (8.80 m^4/s^2 and 56.5 m^2/s for the paper's Table 1); for the
long-range kernel gamma1 diverges (it has no local limit).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...parameters import DEFAULTS as D

__all__ = ["SFMRepulsion", "SFMFriction", "LongRange", "gamma1", "gamma2", "RadialTables"]


@dataclass(frozen=True)
class SFMRepulsion:
    """Phi(d) = (A exp((r_ij - d)/B) + k (r_ij - d)_+)/m, the pair force per unit mass."""

    A: float = D['A']  #: [N]
    B: float = D['B']  #: [m]
    k: float = D['k']  #: [kg/s^2]
    m: float = D['m']  #: [kg]
    r_ij: float = 0.3  #: [m] (two body radii)

    def __call__(self, r):
        r = np.asarray(r, float)
        return (self.A * np.exp((self.r_ij - r) / self.B) + self.k
                * np.maximum(self.r_ij - r, 0.0)) / self.m

    @property
    def support(self) -> float:
        """Radius [m] beyond which the kernel is below 1e-12 of its value at contact."""
        return self.r_ij + self.B * np.log(1e12)

    @property
    def breakpoints(self) -> tuple[float, ...]:
        return (self.r_ij,)


@dataclass(frozen=True)
class SFMFriction:
    """Psi(d) = kappa (r_ij - d)_+/m, the sliding friction per unit mass."""

    kappa: float = D['kappa']  #: [kg/(m s)]
    m: float = D['m']  #: [kg]
    r_ij: float = 0.3  #: [m]

    def __call__(self, r):
        r = np.asarray(r, float)
        return self.kappa * np.maximum(self.r_ij - r, 0.0) / self.m

    @property
    def support(self) -> float:
        return self.r_ij

    @property
    def breakpoints(self) -> tuple[float, ...]:
        return (self.r_ij,)


@dataclass(frozen=True)
class LongRange:
    """strength / (1 + (d/length)^2): the paper's long-range (weak) illustration kernel.

    The paper uses it with unit strength and length to illustrate the weak-interaction
    scaling; it is not calibrated to pedestrians.
    """

    strength: float = 1.0  #: [m^3/s^2 per ped] for phi, [m^2/s per ped] for psi
    length: float = 1.0  #: [m]

    def __call__(self, r):
        r = np.asarray(r, float)
        return self.strength / (1.0 + (r / self.length) ** 2)

    @property
    def support(self) -> float:
        return np.inf

    @property
    def breakpoints(self) -> tuple[float, ...]:
        return ()


def _moment(kernel, power: int) -> float:
    from scipy import integrate  # (here: it takes a quarter of a second to import)

    f = lambda r: float(kernel(r)) * r**power  # noqa: E731
    upper = kernel.support
    if not np.isfinite(upper):
        val, _ = integrate.quad(f, 0.0, np.inf, limit=200)
        return val
    pts = [p for p in kernel.breakpoints if 0 < p < upper]
    val, _ = integrate.quad(f, 0.0, upper, points=pts or None, limit=400, epsabs=0, epsrel=1e-13)
    return val


def gamma1(kernel) -> float:
    """pi int_0^inf phi(r) r^2 dr [m^4/s^2]: the strong-interaction pressure coefficient
    (p = gamma1 rho^2 / 2). Infinite for kernels decaying like 1/r^2 or slower."""
    if not np.isfinite(kernel.support):
        return np.inf
    return np.pi * _moment(kernel, 2)


def gamma2(kernel) -> float:
    """pi int_0^inf psi(r) r dr [m^2/s]: the strong-interaction friction rate per density."""
    if not np.isfinite(kernel.support):
        return np.inf
    return np.pi * _moment(kernel, 1)


@dataclass(frozen=True)
class RadialTables:
    """Radial potentials of a compactly supported kernel, tabulated on a fine grid.

    For the repulsion kernel Phi: ``G(r) = int_r^inf Phi`` and ``FG(r) = int_0^r G(s) s ds``
    (so that ``Phi r_hat = -grad G`` and ``G = Laplacian of a radial potential with
    derivative FG/r``). For the friction kernel Psi: ``J(r) = int_r^inf Psi(s)/s ds``,
    ``Q(r)`` with ``Q' = r J`` and ``Gam(r)`` with ``Gam' = Fg/r``, ``Fg = int_0^r (J - Psi) s
    ds``, so that ``Psi t t^T = grad grad Q - (J - Psi) I``. The double integrals over two
    triangles then become double line integrals over their boundaries.
    """

    dr: float
    r_max: float
    FG: np.ndarray
    Q: np.ndarray
    Gam: np.ndarray
    FG_inf: float
    Fg_inf: float

    @classmethod
    def build(cls, phi, psi, dr: float = 2e-5) -> "RadialTables":
        r_max = max(phi.support if phi is not None else 0.0,
                    psi.support if psi is not None else 0.0)
        r_max = float(min(r_max, 3.0)) + 10 * dr
        r = np.arange(0.0, r_max + dr / 2, dr)
        n = len(r)

        def cumtrapz(y):
            out = np.zeros_like(y)
            out[1:] = np.cumsum(0.5 * (y[1:] + y[:-1]) * dr)
            return out

        FG = np.zeros(n)
        if phi is not None:
            f = phi(r)
            tail = cumtrapz(f[::-1])[::-1]  # int_r^rmax Phi
            G = tail
            FG = cumtrapz(G * r)
        Q = np.zeros(n)
        Gam = np.zeros(n)
        Fg_inf = 0.0
        if psi is not None:
            p = psi(r)
            with np.errstate(divide="ignore", invalid="ignore"):
                integrand = np.where(r > 0, p / np.where(r > 0, r, 1.0), 0.0)
            J = cumtrapz(integrand[::-1])[::-1]
            J[0] = J[1] + (J[1] - J[2])  # log singularity at 0: only r J and J r dr are used
            rJ = r * J
            rJ[0] = 0.0
            Q = cumtrapz(rJ)
            Fg = cumtrapz((J - p) * r)
            Fg_inf = float(Fg[-1])
            with np.errstate(divide="ignore", invalid="ignore"):
                gp = np.where(r > 0, Fg / np.where(r > 0, r, 1.0), 0.0)
            Gam = cumtrapz(gp)
        return cls(dr=dr, r_max=float(r[-1]), FG=FG, Q=Q, Gam=Gam,
                   FG_inf=float(FG[-1]), Fg_inf=Fg_inf)
