"""The social force model on the mesh (the paper's microscopic model): its parameters
(:mod:`~pedmesh.models.sfm.params`), the simulation (:mod:`~pedmesh.models.sfm.simulation`)
and its run object (:mod:`~pedmesh.models.sfm.adapter`), registered as ``sfm``."""

from .adapter import SFMRun
from .entry import ENTRY  # (registers the model)
from .params import SFMNumerics, SocialForceParams
from .simulation import Simulation

__all__ = ["SFMNumerics", "SFMRun", "Simulation", "SocialForceParams"]
