"""Groundwork of the hybrid model (issue 47): people as agents where it matters, a continuum
elsewhere, on one mesh. Not a model yet (not in the registry): what is here is the split of
a mesh into an agent zone and the continuum's part with an exact, per-edge account of
what crosses the interface.

* :mod:`~pedmesh.models.hybrid.zones`: which triangles belong to the agents (fixed polygons,
  the surroundings of exits), and a density trigger with hysteresis that moves cells in
  and out as the crowd comes and goes (not yet used by the coupled run);
* :mod:`~pedmesh.models.hybrid.interface`: the continuum's sub-mesh, each interface edge an
  exit of its own, so that the finite-volume solver counts what leaves through it exactly
  (its outflow per exit), and the deposit of an agent's mass and momentum into the cell it
  enters;
* :mod:`~pedmesh.models.hybrid.coupling`: a first coupled run (a prototype) that keeps the
  count exact.
"""

from .coupling import HybridCount, HybridRun
from .interface import ContinuumPart, deposit, split_mesh
from .zones import DensityTrigger, zone_cells

__all__ = ["ContinuumPart", "DensityTrigger", "HybridCount", "HybridRun", "deposit", "split_mesh",
           "zone_cells"]
