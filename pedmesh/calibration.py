"""The social force model's equation of state, measured, for a calibrated continuum model.

The mean-field closure behind mac1/mac2 treats pair distances as uncorrelated, which gives
the pressure ``gamma1 rho^2 / 2``. Pedestrians keep apart, so the repulsion they actually
feel at a given density is far smaller. This module measures the SFM's pressure per unit
mass, the virial

.. math::  P = \\frac{1}{2|A|} \\sum_{i<j} r_{ij} \\cdot \\frac{f_{ij}}{m}
            + \\frac{1}{2|A|} \\sum_i |v_i|^2,

in periodic boxes (minimum image) of standing crowds, with the simulator's own pair force
(:func:`pedmesh.models.sfm.kernels.pair_force`), and fits a smooth, monotone p(rho) for the
``eos`` continuum model.

Protocol per density (all settable): N pedestrians on a triangular lattice displaced at
random by 15 % of the spacing (disordered, without the huge overlaps of uniform random
points), relaxed for ``relax_time`` under the pair forces and the relaxation towards rest
(desired velocity 0), optionally with small velocity noise, then the virial is averaged over
``sample_time``. Independent replicas give the error estimate (standard error).
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Callable

import numba as nb
import numpy as np

from .errors import ParameterError, PedmeshError
from .io.run_folder import TRAJECTORIES_TXT
from .models.sfm.kernels import pair_force
from .models.continuum.eos_file import DEFAULT_EOS, EOS_FORMAT, load_eos, save_eos
from .models.sfm.params import SocialForceParams
from .mesh.triangulate import triangulate

__all__ = ["CalibrationOptions", "measure_pressure", "calibrate", "fit_eos", "load_eos",
           "save_eos", "lattice_virial", "periodic_virial", "pedestrian_stress",
           "flowing_stress", "eos_pressure", "DEFAULT_EOS", "EOS_FORMAT",
           "measure_fundamental_diagram", "fd_speed_table", "fd_corridor", "FD_PROTOCOL"]

_SFM_KEYS = ("m", "A", "B", "r", "k", "kappa", "shrink", "t_space", "crowd_stretch",
             "crowd_knee")


@dataclass(frozen=True, kw_only=True)
class CalibrationOptions:
    """How the equation of state is measured."""

    densities: tuple[float, ...] = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0,
                                    10.0, 11.0, 12.0)  #: [ped/m^2]
    n: int = 300  #: pedestrians per box
    replicas: int = 3  #: independent boxes per density
    dt: float = 0.002  #: [s] (contacts at 12 ped/m^2 are stiff: friction rates of ~1000/s)
    relax_time: float = 6.0  #: [s]
    sample_time: float = 6.0  #: [s]
    sample_every: float = 0.1  #: [s]
    noise: float = 0.0  #: velocity noise [m/s per sqrt(s)] (Langevin kicks); 0 = at rest
    cutoff: float = 1.2  #: pair force cut-off [m] (as in the simulator)
    seed: int = 0

    def __post_init__(self) -> None:
        if not self.densities or min(self.densities) <= 0:
            raise ParameterError("densities must be positive [ped/m^2]")
        for name in ("dt", "relax_time", "sample_time", "sample_every", "cutoff"):
            if not getattr(self, name) > 0:
                raise ParameterError(f"parameter '{name}' must be positive")
        if self.n < 16 or self.replicas < 2:
            raise ParameterError("use at least 16 pedestrians per box and 2 replicas")
        if len(set(self.densities)) < 2:
            raise ParameterError("an equation of state needs at least 2 distinct densities")
        rho_max = max(self.densities)
        if math.sqrt(self.n / rho_max) < 3 * self.cutoff:
            need = math.ceil(9 * self.cutoff**2 * rho_max)
            raise ParameterError(f"{self.n} pedestrians at {rho_max:g} ped/m^2 make a box "
                                 f"narrower than 3 cut-offs ({3 * self.cutoff:g} m); use "
                                 f"n >= {need}")


# ------------------------------------------------------------------ kernels
@nb.njit(cache=True, nogil=True)
def _periodic_forces(x, v, Lx, Ly, ncx, ncy, rc, rij, A, B, k, kappa, m, F, sij):
    """Pair accelerations in a periodic Lx x Ly box (minimum image) into F; returns
    sum_{i<j} r_ij . f_ij / m (the virial sum per unit mass). ``rij``, ``sij``: the sums of
    two body and two social radii [m] (:func:`standing_social_rij`)."""
    n = x.shape[0]
    invB = 1.0 / B
    inv_m = 1.0 / m
    rc2 = rc * rc
    for i in range(n):
        F[i, 0] = 0.0
        F[i, 1] = 0.0
    # periodic cell list (at least 3 cells per side, so the half stencil visits a pair once)
    cell = np.empty(n, np.int64)
    count = np.zeros(ncx * ncy + 1, np.int64)
    for i in range(n):
        cx = int(x[i, 0] / Lx * ncx) % ncx
        cy = int(x[i, 1] / Ly * ncy) % ncy
        c = cx * ncy + cy
        cell[i] = c
        count[c + 1] += 1
    for c in range(ncx * ncy):
        count[c + 1] += count[c]
    order = np.empty(n, np.int64)
    fill = count[:ncx * ncy].copy()
    for i in range(n):
        order[fill[cell[i]]] = i
        fill[cell[i]] += 1
    vir = 0.0
    for cx in range(ncx):
        for cy in range(ncy):
            c = cx * ncy + cy
            for q in range(5):
                if q == 0:
                    ox, oy = 0, 0
                elif q < 4:
                    ox, oy = 1, q - 2
                else:
                    ox, oy = 0, 1
                c2 = ((cx + ox) % ncx) * ncy + (cy + oy) % ncy
                for a in range(count[c], count[c + 1]):
                    i = order[a]
                    b0 = a + 1 if q == 0 else count[c2]
                    for b in range(b0, count[c2 + 1]):
                        j = order[b]
                        dx = x[i, 0] - x[j, 0]
                        dy = x[i, 1] - x[j, 1]
                        dx -= Lx * math.floor(dx / Lx + 0.5)
                        dy -= Ly * math.floor(dy / Ly + 0.5)
                        d2 = dx * dx + dy * dy
                        if d2 < rc2 and d2 > 0.0:
                            fx, fy = pair_force(dx, dy, math.sqrt(d2), v[j, 0] - v[i, 0],
                                                v[j, 1] - v[i, 1], rij, A, invB, k, kappa,
                                                sij)
                            fx *= inv_m
                            fy *= inv_m
                            F[i, 0] += fx
                            F[i, 1] += fy
                            F[j, 0] -= fx
                            F[j, 1] -= fy
                            vir += dx * fx + dy * fy
    return vir


@nb.njit(cache=True, nogil=True)
def _run_box(x, v, L, nc, rc, rij, A, B, k, kappa, m, tau, dt, n_relax, n_sample, every,
             noise, seed, out_vir, out_kin, sij):
    """SSP-RK3 dynamics of a standing crowd in a periodic box; records the virial and the
    kinetic sums every ``every`` steps of the sampling phase."""
    np.random.seed(seed)
    n = x.shape[0]
    F = np.empty_like(x)
    x1 = np.empty_like(x)
    v1 = np.empty_like(v)
    s = 0
    kick = noise * math.sqrt(dt)
    for step in range(n_relax + n_sample):
        _periodic_forces(x, v, L, L, nc, nc, rc, rij, A, B, k, kappa, m, F, sij)
        for i in range(n):
            for d in range(2):
                x1[i, d] = x[i, d] + dt * v[i, d]
                v1[i, d] = v[i, d] + dt * (F[i, d] - v[i, d] / tau)
        _periodic_forces(x1, v1, L, L, nc, nc, rc, rij, A, B, k, kappa, m, F, sij)
        for i in range(n):
            for d in range(2):
                xa = x1[i, d]
                va = v1[i, d]
                x1[i, d] = 0.75 * x[i, d] + 0.25 * (xa + dt * va)
                v1[i, d] = 0.75 * v[i, d] + 0.25 * (va + dt * (F[i, d] - va / tau))
        _periodic_forces(x1, v1, L, L, nc, nc, rc, rij, A, B, k, kappa, m, F, sij)
        for i in range(n):
            for d in range(2):
                x[i, d] = x[i, d] / 3.0 + 2.0 / 3.0 * (x1[i, d] + dt * v1[i, d])
                v[i, d] = v[i, d] / 3.0 + 2.0 / 3.0 * (v1[i, d] + dt * (F[i, d] - v1[i, d] / tau))
                if kick > 0.0:
                    v[i, d] += kick * np.random.standard_normal()
                x[i, d] = x[i, d] % L
        if step >= n_relax and (step - n_relax) % every == 0 and s < out_vir.shape[0]:
            out_vir[s] = _periodic_forces(x, v, L, L, nc, nc, rc, rij, A, B, k, kappa, m, F, sij)
            kin = 0.0
            for i in range(n):
                kin += v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1]
            out_kin[s] = kin
            s += 1
    return s


def standing_social_rij(p: SocialForceParams) -> float:
    """The sum of two social radii [m] of people who want to stand (desired speed 0, in the
    open: crowding factor 1, :mod:`pedmesh.models.sfm.crowding`): ``2 (r - shrink)``; ``2 r``
    in the paper's model."""
    return 2.0 * (p.r - p.shrink) if p.shrink > 0 else 2.0 * p.r


def crowd_social_rij(p: SocialForceParams, x: np.ndarray, L: float) -> float:
    """The sum of two social radii [m] in a crowd at the positions ``x`` of a periodic box
    of side ``L`` [m], as the social force model gives them: its social radius
    (:func:`pedmesh.models.sfm.kernels.social_radii`) at the desired speed its speed law wants
    at the crowd's mean kernel density (own share included, crowding factor 1: in the
    open; :func:`pedmesh.models.sfm.kernels.desired_speeds`), so the equation of state is
    measured with the space the model's people keep at that density (a box whose radii
    were those of people who want to stand would push far less than the model's crowds
    do). ``2 r`` in the paper's model."""
    if p.shrink <= 0:
        return 2.0 * p.r
    from scipy.spatial import cKDTree

    from .models.sfm.kernels import desired_speeds, social_radii

    R = p.R
    w0 = 1.0 / (math.pi * R * R)
    tree = cKDTree(np.asarray(x, float) % L, boxsize=L)
    pairs = tree.query_pairs(min(3.0 * R, 0.499 * L), output_type="ndarray")
    d = np.linalg.norm(((x[pairs[:, 0]] - x[pairs[:, 1]]) + 0.5 * L) % L - 0.5 * L, axis=1)
    rho = np.array([w0 + 2.0 * w0 * np.exp(-(d / R) ** 2).sum() / len(x)])
    one, ue, rs = np.ones(1), np.empty(1), np.empty(1)
    desired_speeds(1, np.array([p.U_f]), p.kernel_law(), rho, -1.0, p.crowd_stretch > 1.0,
                   one, p.crowd_knee, p.crowd_stretch, ue)
    social_radii(1, np.array([p.r]), ue, p.shrink, p.t_space, p.crowd_stretch > 1.0, one, rs)
    return 2.0 * float(rs[0])


def periodic_virial(x: np.ndarray, L, params: SocialForceParams | None = None,
                    v: np.ndarray | None = None, cutoff: float = 1.2) -> float:
    """Virial pressure per unit mass (1/(2|A|)) sum_{i<j} r_ij . f_ij / m of a configuration
    in a periodic box ``L`` [m] (a side, or (Lx, Ly)); no kinetic part. The simulator's
    pair force (with cut-off) is used."""
    p = params or SocialForceParams()
    Lx, Ly = (float(L), float(L)) if np.ndim(L) == 0 else (float(L[0]), float(L[1]))
    x = np.ascontiguousarray(np.asarray(x, float) % [Lx, Ly])
    v = np.zeros_like(x) if v is None else np.ascontiguousarray(v, dtype=float)
    ncx, ncy = max(3, int(Lx / cutoff)), max(3, int(Ly / cutoff))
    if min(Lx, Ly) < 3 * cutoff:
        raise ParameterError("the periodic box must be at least 3 cut-offs wide")
    F = np.empty_like(x)
    vir = _periodic_forces(x, v, Lx, Ly, ncx, ncy, cutoff, 2 * p.r, p.A, p.B, p.k, p.kappa,
                           p.m, F, standing_social_rij(p))
    return vir / (2.0 * Lx * Ly)


def lattice_virial(rho: float, params: SocialForceParams | None = None, cutoff: float = 1.2,
                   shells: int = 12) -> float:
    """The analytic virial of a perfect triangular lattice at density ``rho``:
    ``P = (rho / 4) sum over lattice vectors R != 0 (|R| < cutoff) of |R| Phi(|R|)``."""
    p = params or SocialForceParams()
    a = math.sqrt(2.0 / (math.sqrt(3.0) * rho))  # lattice constant
    tot = 0.0
    for i in range(-shells, shells + 1):
        for j in range(-shells, shells + 1):
            if i == 0 and j == 0:
                continue
            rx = a * (i + 0.5 * j)
            ry = a * (math.sqrt(3.0) / 2.0) * j
            d = math.hypot(rx, ry)
            if d < cutoff:
                f = (p.A * math.exp((standing_social_rij(p) - d) / p.B)
                     + p.k * max(2 * p.r - d, 0.0))
                tot += d * f / p.m
    return rho / 4.0 * tot


def _initial(rng, n: int, L: float) -> np.ndarray:
    """A triangular lattice of about n points in the box, randomly displaced by 15 % of its
    spacing (exactly n points are kept)."""
    a = math.sqrt(2.0 * L * L / (math.sqrt(3.0) * n))
    ny = max(2, int(round(L / (a * math.sqrt(3.0) / 2.0))))
    nx = max(2, int(math.ceil(n / ny)))
    pts = []
    for j in range(ny):
        for i in range(nx):
            pts.append(((i + 0.5 * (j % 2)) * L / nx, j * L / ny))
    pts = np.array(pts[:n])
    pts += rng.uniform(-0.15, 0.15, pts.shape) * (L / nx)
    return pts % L


def measure_pressure(rho: float, params: SocialForceParams | None = None,
                     options: CalibrationOptions | None = None) -> dict[str, float]:
    """Mean pressure per unit mass (virial + kinetic) [ped/s^2 ...] of a relaxed standing
    crowd at density ``rho``, with its standard error over replicas."""
    p = params or SocialForceParams()
    o = options or CalibrationOptions()
    L = math.sqrt(o.n / rho)
    if L < 3 * o.cutoff:
        raise ParameterError(f"{o.n} pedestrians at {rho} ped/m^2 make a box narrower than 3 "
                             "cut-offs; use more pedestrians")
    nc = max(3, int(L / o.cutoff))
    n_relax = int(round(o.relax_time / o.dt))
    n_sample = int(round(o.sample_time / o.dt))
    every = max(1, int(round(o.sample_every / o.dt)))
    from ._signals import stop_requested

    per = []
    kin = []
    for r in range(o.replicas):
        if stop_requested():  # Ctrl-C / SIGTERM under stop_on_signals: stop between replicas
            raise KeyboardInterrupt
        rng = np.random.default_rng([o.seed, r, int(rho * 1000)])
        x = _initial(rng, o.n, L)
        v = np.zeros_like(x)
        ov = np.zeros(n_sample // every + 1)
        ok = np.zeros_like(ov)
        s = _run_box(x, v, L, nc, o.cutoff, 2 * p.r, p.A, p.B, p.k, p.kappa, p.m, p.tau, o.dt,
                     n_relax, n_sample, every, o.noise, int(rng.integers(2**31)), ov, ok,
                     crowd_social_rij(p, x, L))
        if not np.all(np.isfinite(x)) or not np.all(np.abs(v) < 10.0):
            raise PedmeshError(f"calibration at {rho} ped/m^2 blew up; try a smaller dt "
                               f"(now {o.dt} s)")
        area = L * L
        per.append(ov[:s].mean() / (2 * area))
        kin.append(ok[:s].mean() / (2 * area))
    per = np.array(per)
    kin = np.array(kin)
    tot = per + kin
    return {"rho": rho, "p": float(tot.mean()),
            "p_err": float(tot.std(ddof=1) / math.sqrt(len(tot))),
            "p_virial": float(per.mean()), "p_kinetic": float(kin.mean()),
            "mean_field": None}


def fit_eos(rho: np.ndarray, p: np.ndarray) -> dict[str, list[float]]:
    """A smooth (C1) monotone p(rho): isotonic regression of the measurements, made strictly
    increasing, then a monotone (PCHIP) cubic Hermite interpolant. Returns the nodes, values
    and derivatives (the ``table`` pressure law of the barotropic models)."""
    from scipy.interpolate import PchipInterpolator

    r = np.asarray(rho, float)
    y = np.asarray(p, float)
    order = np.argsort(r)
    r, y = r[order], y[order]
    # pool-adjacent-violators (isotonic, non-decreasing)
    vals = [[v, 1.0] for v in y]
    i = 0
    while i < len(vals) - 1:
        if vals[i][0] > vals[i + 1][0]:
            tot = vals[i][0] * vals[i][1] + vals[i + 1][0] * vals[i + 1][1]
            w = vals[i][1] + vals[i + 1][1]
            vals[i] = [tot / w, w]
            del vals[i + 1]
            i = max(i - 1, 0)
        else:
            i += 1
    iso = np.concatenate([[v] * int(w) for v, w in vals])
    iso = np.maximum(iso, 1e-12)
    for k in range(1, len(iso)):  # strictly increasing
        if iso[k] <= iso[k - 1]:
            iso[k] = iso[k - 1] * (1 + 1e-6) + 1e-12
    f = PchipInterpolator(r, iso)
    d = f.derivative()(r)
    d = np.maximum(d, 1e-12)
    return {"rho": r.tolist(), "p": iso.tolist(), "dp": d.tolist()}


def calibrate(params: SocialForceParams | None = None, options: CalibrationOptions | None = None,
              *, progress: bool = True,
              on_row: Callable[[dict], None] | None = None) -> dict[str, Any]:
    """Measure the equation of state at every density and fit it; returns the calibration
    dictionary (see :func:`save_eos`). ``on_row(partial)`` is called after each density
    with the calibration so far (``"status": "incomplete"``, no fit), so that a caller can
    keep what was measured if the run is interrupted."""
    from tqdm import tqdm

    from ._version import __version__
    from .models.continuum.physics import SFMRepulsion, gamma1

    p = params or SocialForceParams()
    o = options or CalibrationOptions()
    g1 = gamma1(SFMRepulsion(A=p.A, B=p.B, k=p.k, m=p.m, r_ij=2 * p.r))
    t0 = time.perf_counter()
    cal: dict[str, Any] = {
        "format": EOS_FORMAT, "version": 1, "status": "incomplete",
        "pedmesh_version": __version__, "created": time.strftime("%Y-%m-%d"),
        "parameters": {k: getattr(p, k) for k in _SFM_KEYS} | {"tau": p.tau},
        "options": asdict(o), "gamma1": g1, "table": [],
        "units": {"rho": "ped/m^2", "p": "pressure per unit mass [ped/s^2] (m^2/s^2 x ped/m^2)"},
    }
    for rho in tqdm(o.densities, desc="calibrating", unit="density", disable=not progress):
        row = measure_pressure(rho, p, o)
        row["mean_field"] = 0.5 * g1 * rho * rho
        cal["table"].append(row)
        if on_row is not None:
            on_row(cal)
    rows = cal["table"]
    cal["fit"] = fit_eos(np.array([r["rho"] for r in rows]), np.array([r["p"] for r in rows]))
    cal["status"] = "complete"
    cal["seconds"] = time.perf_counter() - t0
    return cal


# ------------------------------------------------------------------ the flowing crowd
@nb.njit(cache=True, nogil=True)
def _pair_stress(x, v, pi, pj, rij, A, B, k, kappa, m, S):
    """Per-pedestrian virial tensors S_i = 1/2 sum_j r_ij (x) f_ij / m over the pairs
    (pi, pj) (half of each pair's r (x) f to each partner)."""
    invB = 1.0 / B
    for q in range(pi.shape[0]):
        i = pi[q]
        j = pj[q]
        dx = x[i, 0] - x[j, 0]
        dy = x[i, 1] - x[j, 1]
        d = math.sqrt(dx * dx + dy * dy)
        if d <= 0.0:
            continue
        fx, fy = pair_force(dx, dy, d, v[j, 0] - v[i, 0], v[j, 1] - v[i, 1], rij, A, invB,
                            k, kappa, rij)
        fx /= 2.0 * m
        fy /= 2.0 * m
        for a in (i, j):
            S[a, 0, 0] += dx * fx
            S[a, 0, 1] += dx * fy
            S[a, 1, 0] += dy * fx
            S[a, 1, 1] += dy * fy


def pedestrian_stress(*, positions: np.ndarray, velocities: np.ndarray,
                      params: SocialForceParams | None = None, cutoff: float = 1.2,
                      kinetic: bool = True, R: float | None = None) -> np.ndarray:
    """(N, 2, 2) per-pedestrian stress per unit mass [m^2/s^2]: the pair virial
    1/2 sum_j r_ij (x) f_ij / m (the simulator's pair force, cut off at ``cutoff`` m; wall
    forces are not bulk stress and are left out) plus, if ``kinetic``, the velocity
    fluctuation v' (x) v' about the kernel-averaged velocity (width ``R``, default the
    model's). The pressure of a region is ``sum_i tr(S_i) / (2 |region|)``."""
    from scipy.spatial import cKDTree

    from .analysis import kernel_velocity

    p = params or SocialForceParams()
    x = np.ascontiguousarray(positions, dtype=float).reshape(-1, 2)
    v = np.ascontiguousarray(velocities, dtype=float).reshape(-1, 2)
    S = np.zeros((len(x), 2, 2))
    if len(x) < 1:
        return S
    pairs = cKDTree(x).query_pairs(cutoff, output_type="ndarray")
    if len(pairs):
        _pair_stress(x, v, np.ascontiguousarray(pairs[:, 0]), np.ascontiguousarray(pairs[:, 1]),
                     2 * p.r, p.A, p.B, p.k, p.kappa, p.m, S)
    if kinetic:
        u = kernel_velocity(positions=x, velocities=v, points=x, R=R or p.R)
        w = v - u
        S += w[:, :, None] * w[:, None, :]
    return S


def eos_pressure(rho, cal: dict | None = None) -> np.ndarray:
    """The calibrated pressure per unit mass p(rho) [ped/s^2] (default: shipped calibration)."""
    from .models.continuum.barotropic import PressureLaw

    fit = (cal or load_eos())["fit"]
    law = PressureLaw.table(fit["rho"], fit["p"], fit["dp"])
    return law.pressure(np.asarray(rho, float))


def flowing_stress(mesh, *, params: SocialForceParams | None = None, every: float = 1.0,
                   bins: np.ndarray | None = None, t_end: float = 1000.0,
                   progress: bool = False) -> dict[str, np.ndarray]:
    """Per-pedestrian virial stress in a full SFM run on ``mesh`` (from its start areas),
    sampled every ``every`` s and binned by the kernel density at the pedestrian.

    Each tensor is turned into the frame of the pedestrian's desired direction e
    (components along e and across it). Returned per bin, as arrays:

    * ``rho``: mean density [ped/m^2] of its samples; ``count``: number of samples;
    * ``p``: pressure ``<rho_i tr S_i / 2>`` [ped/s^2] (virial + kinetic), ``p_virial``;
    * ``normal_diff``: (S_ee - S_nn) / 2 of the bin-mean tensor relative to the pressure
      (positive: pushed harder along the walking direction than across it);
    * ``shear``: ``|S_en|`` of the bin-mean tensor relative to the pressure;
    * ``dev_individual``: mean size of the individual deviators relative to the mean
      individual pressure (anisotropy of single pedestrians' contacts);
    * ``p_eos``: the equilibrium law (shipped calibration) at ``rho``.
    """
    from tqdm import tqdm

    from .models.sfm import SFMNumerics, Simulation

    p = params or SocialForceParams()
    sim = Simulation(mesh, params=p, numerics=SFMNumerics())
    bins = np.arange(0.0, 8.01, 0.5) if bins is None else np.asarray(bins, float)
    nbin = len(bins) - 1
    acc = {k: np.zeros(nbin) for k in ("count", "rho", "p", "p_virial", "tr", "dev")}
    ten = np.zeros((nbin, 2, 2))
    next_t = every
    bar = tqdm(total=sim.n_initial, desc="flowing-crowd stress", unit="ped", disable=not progress)
    while sim.n > 0 and sim.t < t_end - 1e-9:
        sim.step()
        bar.update(sim.n_evacuated - bar.n)
        if sim.t + 1e-9 < next_t:
            continue
        next_t += every
        x, v, rho = sim.positions, sim.velocities, sim.densities
        Sv = pedestrian_stress(positions=x, velocities=v, params=p, kinetic=False)
        S = pedestrian_stress(positions=x, velocities=v, params=p, kinetic=True)
        e = sim.desired_directions()
        e /= np.maximum(np.hypot(e[:, 0], e[:, 1]), 1e-300)[:, None]
        Rm = np.stack([e, np.stack([-e[:, 1], e[:, 0]], axis=1)], axis=2)  # columns e, e_perp
        Sr = np.einsum("nai,nab,nbj->nij", Rm, S, Rm)
        k = np.digitize(rho, bins) - 1
        ok = (k >= 0) & (k < nbin)
        k, r = k[ok], rho[ok]
        t_all = 0.5 * (S[ok, 0, 0] + S[ok, 1, 1])
        dev = np.hypot(0.5 * (S[ok, 0, 0] - S[ok, 1, 1]), 0.5 * (S[ok, 0, 1] + S[ok, 1, 0]))
        for name, val in (("count", 1.0), ("rho", r), ("p", r * t_all), ("tr", t_all),
                          ("p_virial", r * 0.5 * (Sv[ok, 0, 0] + Sv[ok, 1, 1])), ("dev", dev)):
            np.add.at(acc[name], k, val)
        np.add.at(ten, k, Sr[ok])
    bar.close()
    n = acc["count"]
    with np.errstate(invalid="ignore", divide="ignore"):
        mt = ten / n[:, None, None]
        half_tr = 0.5 * (mt[:, 0, 0] + mt[:, 1, 1])
        rho_mean = acc["rho"] / n
        return {
            "rho": rho_mean, "count": n, "p": acc["p"] / n, "p_virial": acc["p_virial"] / n,
            "normal_diff": 0.5 * (mt[:, 0, 0] - mt[:, 1, 1]) / half_tr,
            "shear": np.abs(0.5 * (mt[:, 0, 1] + mt[:, 1, 0])) / half_tr,
            "dev_individual": acc["dev"] / acc["tr"],
            "p_eos": np.where(n > 0, eos_pressure(np.nan_to_num(rho_mean)), np.nan),
        }


# ------------------------------------------------------------------ fundamental diagram
#: How :func:`measure_fundamental_diagram` measures the SFM's speed at a density, for a
#: continuum model's desired-speed law (the ``table`` law of :mod:`pedmesh.speed`):
FD_PROTOCOL = """\
A corridor FD_LENGTH x FD_WIDTH m (40 x 10), its far end (x = 40 m) the exit, filled over
x in [0, FD_FILLED] m (30) at the start density rho0 (the lattice jittered by the seed); the
density [ped/m^2] and mean speed [m/s] (centred differences of the trajectories) of the
people in the box FD_BOX (x in [12, 22] m, y in [2, 8] m: 2 m from the walls) over the
frames t in FD_WINDOW ([3, 6] s: after the acceleration, before the rarefaction from the
crowd's front at x = 30 m reaches the box)."""
#: [ped/m^2] start densities, up to a pressing crowd's (Adrian et al. 2020: 6-9 /m^2)
FD_DENSITIES = (0.25, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5, 6.0, 7.0, 8.0,
                9.0)
FD_LENGTH, FD_WIDTH, FD_FILLED = 40.0, 10.0, 30.0  # [m]
FD_BOX = (12.0, 2.0, 22.0, 8.0)  # [m] x0, y0, x1, y1
FD_WINDOW = (3.0, 6.0)  # [s]
FD_JAM_CAP = 12.0  # [ped/m^2] the jam point is never put beyond this
FD_FPS = 10.0


def _rect(x0, y0, x1, y1):
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


def fd_corridor(rho0: float):
    """The corridor of :func:`measure_fundamental_diagram` filled at ``rho0`` [ped/m^2]."""
    from .geometry import Exit, Room, StartArea

    return Room(_rect(0, 0, FD_LENGTH, FD_WIDTH),
                exits=[Exit("end", [(FD_LENGTH, 0), (FD_LENGTH, FD_WIDTH)])],
                start_areas=[StartArea("crowd", _rect(0.2, 0.2, FD_FILLED, FD_WIDTH - 0.2),
                                       density=rho0)],
                name=f"fd-rho{rho0:g}")


def box_density_speed(traj_file: Path) -> tuple[float, float, int]:
    """Mean density [ped/m^2] and mean speed [m/s] of the people in :data:`FD_BOX` over the
    frames in :data:`FD_WINDOW` of an SFM run's trajectories (centred differences), and the
    number of speed samples."""
    data = np.loadtxt(traj_file, comments="#")
    pid, frame, x, y = data[:, 0].astype(int), data[:, 1].astype(int), data[:, 2], data[:, 3]
    order = np.lexsort((frame, pid))
    pid, frame, x, y = pid[order], frame[order], x[order], y[order]
    same = (pid[2:] == pid[:-2]) & (frame[2:] - frame[:-2] == 2)
    k = np.flatnonzero(same) + 1  # samples with a neighbour frame on each side
    u = np.hypot(x[k + 1] - x[k - 1], y[k + 1] - y[k - 1]) * FD_FPS / 2.0
    t = frame[k] / FD_FPS
    x0, y0, x1, y1 = FD_BOX
    sel = ((t >= FD_WINDOW[0]) & (t <= FD_WINDOW[1]) & (x[k] >= x0) & (x[k] < x1)
           & (y[k] >= y0) & (y[k] < y1))
    frames = np.unique(frame[k][sel])
    if not len(frames):
        return math.nan, math.nan, 0
    rho = sel.sum() / len(frames) / ((x1 - x0) * (y1 - y0))
    return float(rho), float(u[sel].mean()), int(sel.sum())


def measure_fundamental_diagram(preset: str | None = None, seeds: int = 2,
                                overrides: dict | None = None,
                                densities: tuple[float, ...] = FD_DENSITIES,
                                log: Callable[[str], None] | None = None) -> list[dict]:
    """The social force model's fundamental diagram under ``preset`` (with ``overrides``):
    for each start density rho0 in ``densities`` [ped/m^2] and seed 1..``seeds``, the
    density [ped/m^2] and mean speed [m/s] measured in the corridor's box (the protocol of
    :data:`FD_PROTOCOL`). Rows: rho0, seed, density, speed, samples, wall_s."""
    import tempfile

    from .run import run_model

    rows = []
    with tempfile.TemporaryDirectory(prefix="pedmesh-fd-") as tmp:
        for rho0 in densities:
            room = fd_corridor(rho0)
            mesh = triangulate(room)
            for seed in range(1, seeds + 1):
                out = Path(tmp) / f"{rho0:g}-{seed}"
                t0 = time.perf_counter()
                run_model(room, mesh, "sfm", overrides=dict(overrides or {}),
                          t_end=FD_WINDOW[1] + 0.2, out_dir=out, quiet=True, preset=preset,
                          model_options={"seed": seed, "trajectory_rate": FD_FPS},
                          safety=False)  # (a scratch measurement run)
                rho, u, n = box_density_speed(out / TRAJECTORIES_TXT)
                rows.append({"rho0": rho0, "seed": seed, "density": rho, "speed": u,
                             "samples": n, "wall_s": time.perf_counter() - t0})
                if log is not None:
                    log(f"  rho0 {rho0:4g} seed {seed}: density {rho:.3f} /m^2, speed "
                        f"{u:.3f} m/s ({n} samples, {rows[-1]['wall_s']:.1f} s)")
    return rows


def fd_speed_table(rows: list[dict], U_f: float) -> list[tuple[float, float]]:
    """The ``table`` law's points (density [ped/m^2], g) of the measurements of
    :func:`measure_fundamental_diagram`: the (density, speed / ``U_f``) pairs averaged
    over the seeds, sorted by density, made non-increasing (a later point never above an
    earlier one), with 0:1 in front and the jam point where the line through the last two
    points reaches g = 0 (capped at ``FD_JAM_CAP``)."""
    by = {}
    for r in rows:
        if math.isfinite(r["density"]):
            by.setdefault(r["rho0"], []).append((r["density"], r["speed"]))
    pts = sorted((float(np.mean([d for d, _ in v])), float(np.mean([u for _, u in v])) / U_f)
                 for v in by.values())
    out = [(0.0, 1.0)]
    for rho, g in pts:
        if rho <= out[-1][0] + 1e-3:
            continue
        out.append((round(rho, 3), round(min(g, out[-1][1]), 4)))
    (r1, g1), (r2, g2) = out[-2], out[-1]
    slope = (g2 - g1) / (r2 - r1) if r2 > r1 else 0.0
    jam = r2 - g2 / slope if slope < 0 else FD_JAM_CAP
    out.append((round(min(max(jam, r2 + 0.1), FD_JAM_CAP), 3), 0.0))
    return out
