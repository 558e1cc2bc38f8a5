"""Parameters of the social force model (paper Table 1 and the dense-crowd terms) and of
its numerics, as frozen keyword-only dataclasses whose fields are declared (unit, default,
bounds, meaning, source) in :mod:`pedmesh.parameters`; :func:`with_overrides` builds new
ones from ``--param`` overrides."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields


from ...errors import ParameterError
from ... import parameters as P

__all__ = ["SocialForceParams", "SFMNumerics", "with_overrides"]


@dataclass(frozen=True, kw_only=True)
class SocialForceParams:
    """Physical parameters of the social force model: the paper's Table 1 and the terms for
    dense crowds, off by default (the paper's model). Each field's unit, default, bounds,
    meaning and source are declared once in :mod:`pedmesh.parameters`."""

    m: float = P.field("m")
    tau: float = P.field("tau")
    beta: float = P.field("beta")
    U_f: float = P.field("U_f")
    R: float = P.field("R")
    A: float = P.field("A")
    B: float = P.field("B")
    r: float = P.field("r")
    k: float = P.field("k")
    kappa: float = P.field("kappa")
    speed_law: str = P.field("speed_law")
    rho_jam: float = P.field("rho_jam")
    gamma_w: float = P.field("gamma_w")
    speed_table: str = P.field("speed_table")
    density_self: float = P.field("density_self")
    shrink: float = P.field("shrink")
    t_space: float = P.field("t_space")
    vision: float = P.field("vision")
    density_cone: float = P.field("density_cone")
    exit_ghosts: float = P.field("exit_ghosts")
    wall_repulsion: float = P.field("wall_repulsion")
    crowd_stretch: float = P.field("crowd_stretch")
    crowd_knee: float = P.field("crowd_knee")
    queue_width: float = P.field("queue_width")
    crowd_width: float = P.field("crowd_width")
    route_kernel: float | None = P.field("route_kernel")
    route_clearance: float = P.field("route_clearance")

    def __post_init__(self) -> None:
        P.check_fields(self)
        if not self.crowd_width > self.queue_width:
            raise ParameterError(f"parameter 'crowd_width' ({self.crowd_width!r} m) must be "
                                 f"larger than 'queue_width' ({self.queue_width!r} m)")
        if not self.shrink < self.r:
            raise ParameterError(f"parameter 'shrink' must be >= 0 and less than the body "
                                 f"radius r = {self.r:g} m, got {self.shrink!r}")
        self.speed  # (checks the law's name)

    @property
    def speed(self):
        """The desired-speed law (:class:`pedmesh.speed.SpeedLaw`)."""
        from ...speed import SpeedLaw

        return SpeedLaw(self.speed_law, self.U_f, self.beta, self.rho_jam, self.gamma_w,
                        table=self.speed_table)

    def kernel_law(self):
        """The speed law array (:func:`pedmesh.speed.shape`) the social force model reads
        at its Gaussian kernel density, which includes one's own share: with
        ``density_self`` 0 the law is shifted by that share, 1/(pi R^2)."""
        speed = self.speed
        if not self.density_self:
            speed = dataclasses.replace(speed, shift=1.0 / (math.pi * self.R * self.R))
        return speed.array

    def desired_speed(self, rho):
        """U_e(rho) [m/s] (paper eq_desired_speed: U_f exp(-beta rho) with the exponential
        law)."""
        return self.speed(rho)


@dataclass(frozen=True, kw_only=True)
class SFMNumerics:
    """Numerical settings of a social force run (declared in :mod:`pedmesh.parameters`).

    The defaults were chosen by convergence checks (see ``benchmarks/sfm.py`` and the
    docs): halving ``dt`` or re-solving the routes every step changes the evacuation
    curve of the paper's Example 2 by less than 1 %.
    """

    dt: float = P.field("dt")
    route_interval: float = P.field("route_interval")
    route_resolution: float | None = P.field("route_resolution")
    route_refine: float = P.field("route_refine")
    force_cutoff: float = P.field("force_cutoff")
    density_cutoff: float = P.field("density_cutoff")
    density_stages: int = P.field("density_stages")
    max_speed: float = P.field("max_speed")
    output_interval: float = P.field("output_interval")
    sample_interval: float = P.field("sample_interval")
    overlap_tolerance: float = P.field("overlap_tolerance")
    threads: int | None = P.field("threads")

    def __post_init__(self) -> None:
        P.check_fields(self)


def with_overrides(overrides: dict[str, float], *classes_and_defaults) -> list:
    """Split ``overrides`` over the given dataclass instances; unknown names are an error."""
    known = {f.name for obj in classes_and_defaults for f in fields(obj)}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise ParameterError(
            f"unknown parameter '{unknown[0]}' (known: {', '.join(sorted(known))})"
        )
    out = []
    for obj in classes_and_defaults:
        mine = {k: v for k, v in overrides.items() if k in {f.name for f in fields(obj)}}
        out.append(dataclasses.replace(obj, **mine))
    return out
