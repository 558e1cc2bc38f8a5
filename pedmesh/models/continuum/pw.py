"""``pw``: the Payne-Whitham model, a barotropic model with the isothermal pressure
``c0^2 rho`` and relaxation to the desired velocity ``U_e(rho) e``
(:mod:`~pedmesh.models.continuum.barotropic`)."""

from __future__ import annotations

from ... import parameters as P
from ...parameters import DEFAULTS as D
from .adapter import BASE_PARAMETERS, register_continuum_model
from .barotropic import BarotropicModel, PressureLaw

__all__ = ["PayneWhitham"]


class PayneWhitham(BarotropicModel):
    """Payne-Whitham: momentum flux rho u (x) u + c0^2 rho I, relaxation to U_e(rho) e."""

    def __init__(self, c0: float = D['c0'], **kw) -> None:
        P.get("c0").check(c0, physical=False)
        super().__init__("pw", PressureLaw.isothermal(c0), **kw)
        self.c0 = float(c0)

    def parameters(self) -> dict:
        return {"c0": self.c0, **super().parameters()}


register_continuum_model("pw", PayneWhitham, ("c0",) + BASE_PARAMETERS,
                         aliases=("payne-whitham",), surface=True,
                         description="Payne-Whitham: isothermal pressure c0^2 rho, relaxation to "
                                     "U_e")
