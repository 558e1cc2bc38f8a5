"""Continuum models, registered by name."""

from . import advection, barotropic, derived, eos, rdue  # noqa: F401  (registration)
from .base import MACRO_MODELS, MacroModel, macro_model, register_macro_model

__all__ = ["MACRO_MODELS", "MacroModel", "macro_model", "register_macro_model"]
