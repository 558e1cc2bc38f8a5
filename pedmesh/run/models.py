"""Model registry of ``pedmesh run``: each model name maps to an adapter that builds the
model from a room, a mesh and ``--param`` overrides, steps it, and writes its outputs."""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from ..errors import ParameterError
from .output import RunWriter, evacuation_times

__all__ = ["MODELS", "register_model", "get_model", "SFMRun"]

MODELS: dict[str, Callable[..., Any]] = {}
ALIASES: dict[str, str] = {}


def register_model(name: str, factory: Callable[..., Any], aliases: tuple[str, ...] = ()) -> None:
    """Register a model adapter factory under ``name`` (and aliases)."""
    MODELS[name] = factory
    for a in aliases:
        ALIASES[a] = name


def get_model(name: str) -> tuple[str, Callable[..., Any]]:
    """The canonical name and factory of a model; a clear error for unknown names."""
    key = ALIASES.get(name, name)
    if key not in MODELS:
        known = ", ".join(sorted(MODELS))
        raise ParameterError(f"unknown model '{name}' (models: {known})")
    return key, MODELS[key]


class SFMRun:
    """The social force model behind the shared run contract."""

    name = "sfm"

    def __init__(self, room, mesh, overrides: dict[str, float], *, static_routes: bool = False,
                 positions: np.ndarray | None = None) -> None:
        from ..micro import SFMNumerics, Simulation, SocialForceParams
        from ..micro.params import with_overrides

        self.params, self.numerics = with_overrides(overrides, SocialForceParams(), SFMNumerics())
        self.sim = Simulation(mesh, positions, params=self.params, numerics=self.numerics,
                              reroute=not static_routes)
        self.mesh = mesh
        self.static_routes = static_routes
        self.sample_interval = self.numerics.sample_interval
        self.output_interval = self.numerics.output_interval

    @property
    def t(self) -> float:
        return self.sim.t

    @property
    def dt(self) -> float:
        return self.numerics.dt

    @property
    def n_initial(self) -> int:
        return self.sim.n_initial

    @property
    def evacuated(self) -> float:
        return float(self.sim.n_evacuated)

    @property
    def remaining(self) -> float:
        return float(self.sim.n)

    @property
    def done(self) -> bool:
        return self.sim.n == 0

    def step(self) -> None:
        self.sim.step()

    def parameters(self) -> dict[str, Any]:
        from dataclasses import asdict

        return {**asdict(self.params), **asdict(self.numerics),
                "reroute": not self.static_routes}

    def outflow_rates(self) -> np.ndarray:
        """Flow [ped/s] through each exit from the kernel density and kernel velocity at the
        exit (the paper's f_c for the particle model)."""
        from ..analysis import particle_outflow

        return particle_outflow(mesh=self.mesh, positions=self.sim.positions,
                                velocities=self.sim.velocities, R=self.params.R)

    def flush_records(self, writer: RunWriter) -> None:
        """Append the pedestrians who left since the last call to exits.csv."""
        sim = self.sim
        done = np.flatnonzero(np.isfinite(sim.exit_time))
        new = done[~np.isin(done, getattr(self, "_written", np.zeros(0, np.int64)))]
        if len(new) or not hasattr(self, "_written"):
            new = new[np.argsort(sim.exit_time[new], kind="stable")]
            names = self.mesh.exit_names
            writer.append_rows("exits.csv", "id,exit,t",
                               [f"{i},{names[sim.exit_id[i]]},{sim.exit_time[i]:.4f}" for i in new])
            self._written = done

    def write_frame(self, writer: RunWriter, frame: int) -> None:
        from ..analysis import kernel_velocity

        sim = self.sim
        v = sim.velocities
        writer.pedestrian_frame(sim.t, sim.positions, {
            "id": sim.active_ids.astype(np.int64),
            "velocity": v,
            "speed": np.hypot(v[:, 0], v[:, 1]) if len(v) else np.zeros(0),
            "density": sim.densities,
        })
        kv = kernel_velocity(positions=sim.positions, velocities=v, points=self.mesh.points,
                             R=self.params.R)
        writer.density_frame(sim.t, self.mesh, point_data={"density": sim.vertex_density(),
                                                           "velocity": kv})
        writer.trajectory_frame(frame, sim.active_ids, sim.positions, 1.0 / self.output_interval,
                                f"social force model, output every {self.output_interval:g} s")

    def summary(self) -> dict[str, Any]:
        sim = self.sim
        t50, t90, t100 = evacuation_times(sim.exit_time, sim.n_initial)
        per_exit = np.bincount(sim.exit_id[sim.exit_id >= 0], minlength=len(self.mesh.exit_names))
        tm = sim.timers
        return {
            "n_initial": sim.n_initial,
            "n_evacuated": sim.n_evacuated,
            "t_evac_50": t50,
            "t_evac_90": t90,
            "t_evac_100": t100,
            "steps": sim.steps,
            "dt": self.numerics.dt,
            "exits": {n: int(c) for n, c in zip(self.mesh.exit_names, per_exit)},
            "reflections": sim.n_reflections,
            "frame_rate": 1.0 / self.output_interval,
            "time_split_s": {"forces": tm.forces, "settle": tm.settle, "routing": tm.routing},
        }


def _sfm_factory(room, mesh, overrides, **kw):
    return SFMRun(room, mesh, overrides, **kw)


register_model("sfm", _sfm_factory, aliases=("sf", "sf1", "social-force"))


def _macro_factory(model: str, params: set[str]):
    def factory(room, mesh, overrides, **kw):
        from ..macro.run import MacroRun

        return MacroRun(room, mesh, overrides, model=model, model_params=params, **kw)

    return factory


register_model("pw", _macro_factory("pw", {"c0", "U_f", "beta", "tau", "rho_cut", "u_max"}),
               aliases=("payne-whitham",))
register_model("rdue", _macro_factory("rdue", {"U_f", "beta"}), aliases=("hughes",))
_BASE = {"U_f", "beta", "tau", "rho_cut", "u_max"}
_SFM = {"A", "B", "k", "kappa", "m", "r"}
register_model("mac1", _macro_factory("mac1", _BASE | _SFM | {"walls", "friction", "cutoff",
                                                           "split_friction"}))
for _name in ("mac2-local", "mac2-local-friction", "mac2-nonlocal", "mac2-nonlocal-friction"):
    register_model(_name, _macro_factory(_name, _BASE | _SFM | {"lr_strength", "lr_length", "gamma1"}))
register_model("eos", _macro_factory("eos", _BASE | _SFM | {"calibration"}),
               aliases=("calibrated",))
