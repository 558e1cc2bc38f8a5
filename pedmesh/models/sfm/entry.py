"""The social force model's registry entry: :class:`~pedmesh.models.sfm.adapter.SFMRun`
on a room, :class:`~pedmesh.models.sfm.building.BuildingSFMRun` on a building's surface."""

from __future__ import annotations

from dataclasses import fields

from ...mesh.surface import SurfaceMesh
from ..registry import PARTICLES, ModelEntry, register_model
from .adapter import SFMRun
from .building import BuildingSFMRun
from .params import SFMNumerics, SocialForceParams

__all__ = ["ENTRY", "build"]


def build(room, mesh, overrides, **options):
    """The run object of the social force model on ``mesh`` (a room's or a building's)."""
    if isinstance(mesh, SurfaceMesh):
        return BuildingSFMRun(room, mesh, overrides, **options)
    return SFMRun(room, mesh, overrides, **options)


#: the social force model's registry entry
ENTRY = register_model(ModelEntry(
    name="sfm", build=build,
    parameters=tuple(f.metadata["parameter"] for cls in (SocialForceParams, SFMNumerics)
                     for f in fields(cls)),
    scale=PARTICLES,
    options=frozenset({"static_routes", "positions", "trajectory_rate", "seed"}),
    random=True, aliases=("sf", "sf1", "social-force"),
    description="the social force model of the paper (one Newton equation per pedestrian)"))
