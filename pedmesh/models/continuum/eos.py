"""``eos``: a Payne-Whitham-type model whose pressure is the social force model's measured
equation of state.

::

    rho_t + div(rho u) = 0
    (rho u)_t + div(rho u (x) u + p(rho) I) = rho (U_e(rho) e - u) / tau

with ``p(rho)`` the virial pressure per unit mass of the SFM measured by
``pedmesh calibrate`` (:mod:`pedmesh.calibration`) and read from a calibration file (default:
the one shipped for the default parameters, Table 1). The default exit condition is the exact
Godunov flux into empty space (``exit=godunov``), which is consistent with any barotropic law.

The calibration holds for the SFM parameters it was measured with; when the run's SFM
parameters (given with ``--param A=...`` etc.) differ, the model says so in
:attr:`EquationOfStateModel.warnings` (printed by ``pedmesh run`` and kept in summary.json).

``exit_kernel`` [m] (0: off; the ``validated`` preset sets the social force model's kernel
width R): near an exit the speed law is read at the density the social force model's people
see there, lowered by the kernel's mass beyond the exit
(:mod:`pedmesh.models.continuum.exit_kernel`); ``exit_cone`` (the social force model's
``density_cone``) weighs that mass as its people heading out see it. ``lookahead`` (an
option, off in every preset) reads the law at the density ahead, as the social force
model's people with their ``density_cone`` read theirs: the crowd's density averaged with
that kernel and a cone about the desired direction
(:mod:`pedmesh.models.continuum.lookahead`; nonlocal).
"""

from __future__ import annotations

import math

import numpy as np

from ...errors import ParameterError
from .barotropic import BarotropicModel, PressureLaw
from .adapter import BASE_PARAMETERS, SFM_PARAMETERS, register_continuum_model
from .eos_file import DEFAULT_EOS, load_eos
from ...parameters import DEFAULTS as D

__all__ = ["EquationOfStateModel"]

#: SFM parameters a calibration depends on (tau is also the continuum's relaxation time)
SFM_KEYS = ("A", "B", "k", "kappa", "m", "r", "tau")


class EquationOfStateModel(BarotropicModel):
    """Barotropic model with the calibrated SFM pressure (see module docstring)."""

    #: u_max = 1.5 U_f: the measured pressure is weak, and crowd edges faster than 1.5 U_f
    #: are a film that only shortens the time step (Example 2: T50 and T90 the same to
    #: 0.01 s with 1.3, 1.5 and 2.5 U_f; the semi-implicit run takes 987 steps with 1.5 U_f
    #: against 1,447 with 2.5 U_f)
    default_u_max = 1.5

    def __init__(self, calibration: str | None = None, *, U_f: float = D['U_f'],
                 beta: float = D['beta'], tau: float = D['tau'],
                 rho_cut: float = D['rho_cut'], u_max: float | None = None,
                 speed_law: str = D['speed_law'], rho_jam: float = D['rho_jam'],
                 gamma_w: float = D['gamma_w'], rho_shift: float = D['rho_shift'],
                 speed_table: str = D['speed_table'], exit_kernel: float = D['exit_kernel'],
                 exit_cone: float = D['exit_cone'], lookahead: float = D['lookahead'],
                 **sfm) -> None:
        unknown = set(sfm) - set(SFM_KEYS)
        if unknown:
            raise ParameterError(f"unknown parameter '{sorted(unknown)[0]}'")
        cal = load_eos(calibration)
        fit = cal["fit"]
        law = PressureLaw.table(fit["rho"], fit["p"], fit["dp"])
        super().__init__("eos", law, U_f=U_f, beta=beta, tau=tau, rho_cut=rho_cut,
                         u_max=u_max, default_exit="godunov", speed_law=speed_law,
                         rho_jam=rho_jam, gamma_w=gamma_w, rho_shift=rho_shift,
                         speed_table=speed_table)
        self.calibration = str(calibration) if calibration else str(DEFAULT_EOS)
        self.calibration_parameters = dict(cal.get("parameters", {}))
        # the SFM this run stands for: Table 1 defaults with the overrides given
        run_sfm = {k: float(sfm.get(k, D[k])) for k in SFM_KEYS}
        run_sfm["tau"] = float(tau)
        self.sfm = run_sfm
        self.warnings: list[str] = []
        diff = [f"{k}={run_sfm[k]:g} (calibrated for {self.calibration_parameters[k]:g})"
                for k in SFM_KEYS if k in self.calibration_parameters
                and not math.isclose(run_sfm[k], float(self.calibration_parameters[k]),
                                     rel_tol=1e-9)]
        if diff:
            self.warnings.append(
                f"eos: the calibration {self.calibration} was measured for other social force "
                f"parameters: {', '.join(diff)}; recalibrate with 'pedmesh calibrate --param "
                "NAME=VALUE ... -o eos.json' and run with --param calibration=eos.json")
        self.rho_range = (float(fit["rho"][0]), float(fit["rho"][-1]))
        #: [m] the width of the kernel beyond exits (0: off; see the module docstring)
        self.exit_kernel = float(exit_kernel)
        #: the density cone of the social force model's people at exits (0: isotropic)
        self.exit_cone = float(exit_cone)
        #: the density cone of the law's read ahead (0: off; needs exit_kernel > 0)
        self.lookahead = float(lookahead)
        if self.lookahead > 0 and not self.exit_kernel > 0:
            raise ParameterError("eos: lookahead reads the density ahead with the kernel of "
                                 "width exit_kernel; set exit_kernel > 0 (e.g. the social "
                                 "force model's R, 0.7 m)")
        self._ahead = None
        self._static_seen = None
        #: (m, 3) the factor of the density the speed law is read at, per interior point
        #: (None: 1 everywhere; set by :meth:`bind`, read by the relaxation kernels)
        self.seen = None

    def bind(self, mesh) -> None:
        super().bind(mesh)
        self.seen = None
        if self.exit_kernel > 0:
            from .exit_kernel import exit_kernel_mass, interior_points

            pts = interior_points(mesh)
            cells = np.repeat(np.arange(len(pts)), 3)
            w = exit_kernel_mass(mesh, pts.reshape(-1, 2), cells, self.exit_kernel,
                                 self.exit_cone)
            if np.any(w > 0):
                self.seen = np.ascontiguousarray((1.0 - w).reshape(-1, 3))
        self._ahead = None
        if self.lookahead > 0:
            from .lookahead import Lookahead

            self._ahead = Lookahead(mesh, self.exit_kernel, self.lookahead)
            self._static_seen = (np.ones((mesh.n_triangles, 3)) if self.seen is None
                                 else self.seen.copy())
            self.seen = self._static_seen.copy()

    def _read_ahead(self, rho_pts: np.ndarray, ex: np.ndarray, ey: np.ndarray,
                    active: np.ndarray | None = None) -> None:
        """:attr:`seen` from the density ahead of each cell: the points' densities
        ``rho_pts`` (m, 3) and desired directions (3 m,); cells not ``active`` are empty
        (the solver leaves their points unset)."""
        m = len(rho_pts)
        rbar = rho_pts.mean(axis=1)
        if active is not None:
            rbar = np.where(np.asarray(active, bool), rbar, 0.0)
        exc = np.asarray(ex).reshape(m, 3).mean(axis=1)
        eyc = np.asarray(ey).reshape(m, 3).mean(axis=1)
        n = np.hypot(exc, eyc)
        ok = n > 0
        exc[ok] /= n[ok]
        eyc[ok] /= n[ok]
        ahead = self._ahead(rbar, exc, eyc)
        ratio = np.ones(m)
        live = rbar > self.rho_vac
        ratio[live] = ahead[live] / rbar[live]
        np.multiply(self._static_seen, ratio[:, None], out=self.seen)

    def source_mean(self, Vi, ex, ey, dQ, cact):
        if self._ahead is not None:
            self._read_ahead(Vi[:, :, 0], ex, ey, cact)
        super().source_mean(Vi, ex, ey, dQ, cact)

    def source(self, q, ex, ey):
        if self._ahead is not None:
            self._read_ahead(q[:, 0].reshape(-1, 3), ex, ey)
        return super().source(q, ex, ey)

    def parameters(self) -> dict:
        return {"calibration": self.calibration, "exit_kernel": self.exit_kernel,
                "exit_cone": self.exit_cone, "lookahead": self.lookahead,
                **super().parameters(),
                **{k: v for k, v in self.sfm.items() if k != "tau"}}


register_continuum_model("eos", EquationOfStateModel,
                         BASE_PARAMETERS + SFM_PARAMETERS + ("calibration", "exit_kernel",
                                                             "exit_cone", "lookahead"),
                         aliases=("calibrated",), surface=True,
                         description="Payne-Whitham-type with the social force model's measured "
                                     "equation of state")
