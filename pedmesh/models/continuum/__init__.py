"""The continuum models: density (and momentum) on the mesh, solved by finite-volume WENO
with SSP Runge-Kutta (:mod:`~pedmesh.models.continuum.solver`). Each model is a
:class:`~pedmesh.models.continuum.base.MacroModel` registered, with its parameters, by
:func:`~pedmesh.models.continuum.adapter.register_continuum_model` in the one model
registry (the built-in ones, :mod:`~pedmesh.models.continuum.eos`,
:mod:`~pedmesh.models.continuum.rdue`, :mod:`~pedmesh.models.continuum.pw` and
:mod:`~pedmesh.models.continuum.derived`, when the registry first needs them:
:data:`pedmesh.models.registry.BUILTINS`); :class:`~pedmesh.models.continuum.adapter.MacroRun`
runs any of them."""

from .adapter import MacroRun, macro_model, register_continuum_model
from .base import MacroModel

__all__ = ["MacroModel", "MacroRun", "macro_model", "register_continuum_model"]
