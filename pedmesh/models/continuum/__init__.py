"""The continuum models: density (and momentum) on the mesh, solved by finite-volume WENO
with SSP Runge-Kutta (:mod:`~pedmesh.models.continuum.solver`). Each model is a
:class:`~pedmesh.models.continuum.base.MacroModel` registered, with its parameters, by
:func:`~pedmesh.models.continuum.adapter.register_continuum_model` in the one model
registry; :class:`~pedmesh.models.continuum.adapter.MacroRun` runs any of them."""

from . import derived, eos, pw, rdue  # noqa: F401  (registration)
from .adapter import MacroRun, macro_model, register_continuum_model
from .base import MacroModel

__all__ = ["MacroModel", "MacroRun", "macro_model", "register_continuum_model"]
