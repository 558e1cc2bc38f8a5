"""The microscopic model: the social force model on the mesh."""

from .params import SFMNumerics, SocialForceParams
from .simulation import Simulation

__all__ = ["SFMNumerics", "Simulation", "SocialForceParams"]
