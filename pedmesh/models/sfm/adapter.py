"""The social force model behind the run protocol (:class:`SFMRun`), and its registry
entry."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ...errors import ParameterError
from ...io.run_folder import EXITS, OUTFLOW_KERNEL
from ...analysis.evacuation import evacuation_times

__all__ = ["SFMRun"]


class SFMRun:
    """The social force model behind the shared run contract
    (:class:`~pedmesh.models.protocol.RunModel`).

    ``seed`` (an integer) moves the start lattice at random, repeatably
    (:func:`pedmesh.models.sfm.placement.seeded_positions`); without it the lattice is used.
    ``trajectory_rate`` [frames/s] is the rate of trajectories.txt / trajectories.sqlite
    (default 10): frame k holds every pedestrian inside at the first step at or after
    t = k / rate, and each pedestrian who left since the previous frame once more, at the
    point where they crossed the exit (their last row).
    """

    name = "sfm"

    def __init__(self, room, mesh, overrides: dict[str, float], *, static_routes: bool = False,
                 positions: np.ndarray | None = None, trajectory_rate: float = 10.0,
                 seed: int | None = None) -> None:
        from .params import SFMNumerics, SocialForceParams
        from .simulation import Simulation
        from .params import with_overrides

        self.params, self.numerics = with_overrides(overrides, SocialForceParams(), SFMNumerics())
        if room is not None and getattr(mesh, "room", None) is not room \
                and dataclasses.is_dataclass(mesh):
            # the crowd (start areas, entrances) is the run's room's, not that of the room
            # the mesh was made from (the driver checked that their walls and exits match)
            mesh = dataclasses.replace(mesh, room=room)
        rate = trajectory_rate
        self._check_rate(rate)
        if seed is not None and positions is None:
            from .placement import seeded_positions

            if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
                raise ParameterError(f"seed must be a non-negative integer, got {seed!r}")
            positions = seeded_positions(room if room is not None else mesh.room, int(seed),
                                         radius=self.params.r)
        self.seed = seed
        # who the start areas' people are (premovement, speeds, radii, exits), drawn with
        # the seed (0 without one) when the room's start areas say so
        population = None
        src = room if room is not None else mesh.room
        if src is not None and any(
                getattr(a, k) is not None for a in src.start_areas
                for k in ("premovement", "speed", "radius", "exits", "arrivals")):
            from ...population import draw_population

            n = len(positions) if positions is not None else None
            counts = [len(a.positions(src.walkable)) for a in src.start_areas]
            if n is None or n == sum(counts):
                population = draw_population(src, counts, seed=0 if seed is None else seed)
        self.population = population
        walk = self._walking_mesh(room, mesh)
        self.sim = Simulation(walk, positions, params=self.params, numerics=self.numerics,
                              reroute=not static_routes, population=population, seed=seed,
                              own_mesh=walk is not mesh)
        self.mesh = mesh
        room = room if room is not None else mesh.room
        self._finish_init(static_routes, rate, room.walkable.wkt if room is not None else None)

    def _walking_mesh(self, room, mesh):
        """The mesh the pedestrians walk on and the routes are solved on: with
        ``route_resolution``, the room's route mesh (:func:`~pedmesh.mesh.route_mesh.
        route_mesh`), whatever the run's mesh (which then carries the output); without it,
        or for a bare mesh without a room, the run's mesh."""
        res = self.numerics.route_resolution
        site = room if room is not None else getattr(mesh, "room", None)
        self.route_mesh = None
        if res is None or site is None:
            return mesh
        from ...mesh.route_mesh import route_mesh

        kernel = self.params.route_kernel if self.params.route_kernel is not None \
            else self.params.R
        self.route_mesh = route_mesh(site, resolution=res, kernel=kernel,
                                     clearance=self.params.route_clearance,
                                     refine=self.numerics.route_refine)
        return self.route_mesh

    def _check_rate(self, rate: float) -> None:
        """A one-line error for a trajectory rate that is not positive or above one frame per
        time step."""
        if not (isinstance(rate, (int, float)) and math.isfinite(rate) and rate > 0):
            raise ParameterError(f"trajectory rate must be a positive number of frames per "
                                 f"second, got {rate!r}")
        if rate * self.numerics.dt > 1.0 + 1e-9:
            raise ParameterError(f"trajectory rate {rate:g} /s is above one frame per time "
                                 f"step (dt = {self.numerics.dt:g} s)")

    def _finish_init(self, static_routes: bool, rate: float, walkable_wkt: str | None) -> None:
        """The output settings and records, once ``sim`` is built."""
        self.static_routes = static_routes
        self.sample_interval = self.numerics.sample_interval
        self.output_interval = self.numerics.output_interval
        self.trajectory_rate = float(rate)
        self.warnings: list[str] = []
        steps = 1.0 / (rate * self.numerics.dt)
        if abs(steps - round(steps)) > 1e-6:
            self.warnings.append(f"1 / (trajectory rate x dt) = {steps:.4g} is not a whole "
                                 "number: trajectory frames are up to one time step late")
        self._walkable_wkt = walkable_wkt
        n = self.sim.n_initial
        self._traj_frame = 0  # the next trajectory frame
        self._traj_out = np.zeros(n, bool)  # leavers whose last trajectory row is written
        self._exits_out = np.zeros(n, bool)  # leavers written to exits.csv
        self._next_record = 0.0

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
        """Pedestrians inside, and still to arrive through an entrance."""
        return float(self.sim.n + self.sim.n_waiting)

    @property
    def done(self) -> bool:
        return self.sim.finished

    def step(self, t_limit: float = math.inf) -> None:
        """One step of the fixed dt (``t_limit`` is not needed: frames fall on steps)."""
        self.sim.step()

    def parameters(self) -> dict[str, Any]:
        from dataclasses import asdict

        out = {**asdict(self.params), **asdict(self.numerics),
               "reroute": not self.static_routes, "trajectory_rate": self.trajectory_rate,
               "seed": self.seed}
        if self.population is not None:  # what was drawn: min, mean, max of each
            sim = self.sim
            mmm = lambda a: [float(a.min()), float(a.mean()), float(a.max())]  # noqa: E731
            groups = np.bincount(sim.toff // max(sim.mesh.n_triangles, 1),
                                 minlength=len(sim._targets))
            out["population"] = {
                "premovement_s": mmm(self.population.premovement),
                "free_speed_m_s": mmm(np.where(np.isnan(self.population.speed),
                                               self.params.U_f, self.population.speed)),
                "radius_m": mmm(np.where(np.isnan(self.population.radius), self.params.r,
                                         self.population.radius)),
                "exit_groups": {("any" if not t else "+".join(t)): int(c)
                                for t, c in zip(sim._targets, groups)},
            }
        return out

    def exit_counts(self) -> np.ndarray:
        """Pedestrians [ped] who crossed each exit so far."""
        ids = self.sim.exit_id
        return np.bincount(ids[ids >= 0], minlength=len(self.mesh.exit_names)).astype(float)

    def kernel_outflow(self, positions: np.ndarray | None = None,
                       velocities: np.ndarray | None = None) -> np.ndarray:
        """Flow [ped/s] through each exit from the kernel density and kernel velocity at the
        exit (the paper's f_c for the particle model), of the crowd now or of the
        ``positions`` [m] and ``velocities`` [m/s] given. It sees only the pedestrians
        still inside, so it reads about half the crossing rate (outflow_kernel.csv)."""
        from ...analysis import particle_outflow

        if positions is None:
            positions, velocities = self.sim.positions, self.sim.velocities
        return particle_outflow(mesh=self.mesh, positions=positions, velocities=velocities,
                                R=self.params.R)

    def record(self, writer, final: bool = False) -> None:
        """Trajectory frames when due; every sample interval exits.csv rows and the kernel
        outflow (outflow_kernel.csv)."""
        sim = self.sim
        t = sim.t
        if t >= self._traj_frame / self.trajectory_rate - 1e-9 or final:
            self._trajectory_frame(writer)
        if t >= self._next_record - 1e-9 or final:
            self._next_record += self.sample_interval * max(
                1, math.floor((t - self._next_record) / self.sample_interval + 1e-9) + 1)
            # computed where the writer writes (on its own thread, if it has one)
            writer.call(_kernel_outflow_row, self.kernel_outflow, list(self.mesh.exit_names),
                        t, sim.positions, sim.velocities)
            new = np.flatnonzero(np.isfinite(sim.exit_time) & ~self._exits_out)
            new = new[np.argsort(sim.exit_time[new], kind="stable")]
            names = self.mesh.exit_names
            writer.append_rows(EXITS, ["id", "exit", "t"],
                               [[int(i), names[sim.exit_id[i]], f"{sim.exit_time[i]:.4f}"]
                                for i in new])
            self._exits_out[new] = True

    def _trajectory_frame(self, writer) -> None:
        sim = self.sim
        left = np.flatnonzero(np.isfinite(sim.exit_time) & ~self._traj_out)
        if self._traj_frame > 0 and sim.t <= (self._traj_frame - 1) / self.trajectory_rate \
                + 1e-9 and len(left) == 0:
            return  # the final call at a time already written
        v = sim.velocities
        speed = np.hypot(v[:, 0], v[:, 1])
        heading = np.divide(v, speed[:, None], out=np.zeros_like(v), where=speed[:, None] > 0)
        ids = np.concatenate([sim.active_ids, left])
        points = np.concatenate([sim.positions, sim.exit_point[left]])
        ori = np.concatenate([heading, np.zeros((len(left), 2))])
        writer.trajectory_frame(self._traj_frame, ids, points, self.trajectory_rate,
                                f"social force model, {self.trajectory_rate:g} frames/s",
                                orientation=ori, walkable_wkt=self._walkable_wkt)
        self._traj_out[left] = True
        self._traj_frame += 1

    def write_frame(self, writer, frame: int) -> None:
        sim = self.sim
        v = sim.velocities
        writer.pedestrian_frame(sim.t, sim.positions, {
            "id": sim.active_ids.astype(np.int64),
            "velocity": v,
            "speed": np.hypot(v[:, 0], v[:, 1]) if len(v) else np.zeros(0),
            "density": sim.densities,
        })
        writer.call(_density_frame, sim.t, self.mesh, sim.density_at(self.mesh.points),
                    sim.positions, v, self.params.R)

    def summary(self) -> dict[str, Any]:
        sim = self.sim
        t50, t90, t100 = evacuation_times(sim.exit_time, sim.n_initial)
        per_exit = np.bincount(sim.exit_id[sim.exit_id >= 0], minlength=len(self.mesh.exit_names))
        tm = sim.timers
        extra = {}
        if self.route_mesh is not None:  # walked on a route mesh of its own
            extra["route_mesh"] = {"triangles": int(self.route_mesh.n_triangles),
                                   "vertices": int(self.route_mesh.n_points),
                                   "resolution_m": self.numerics.route_resolution}
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
            "frame_rate": self.trajectory_rate,
            "trajectory_frames": self._traj_frame,
            "time_split_s": {"forces": tm.forces, "settle": tm.settle, "routing": tm.routing},
            **extra,
        }


def _kernel_outflow_row(writer, outflow, names, t: float, positions: np.ndarray,
                        velocities: np.ndarray) -> None:
    """The row of outflow_kernel.csv at time ``t`` [s]: ``outflow(positions, velocities)``
    [ped/s] per exit (:meth:`SFMRun.kernel_outflow`)."""
    f = outflow(positions, velocities)
    # rows as fields: the writer quotes exit names with commas or newlines
    writer.append_rows(OUTFLOW_KERNEL, ["t", *names],
                       [[f"{t:.4f}", *(f"{v:.6g}" for v in f)]])


def _density_frame(writer, t: float, mesh, density: np.ndarray, positions: np.ndarray,
                   velocities: np.ndarray, R: float) -> None:
    """A frame of density.pvd: the kernel density [ped/m^2] at the vertices and the kernel
    velocity [m/s] there of the crowd at ``positions`` [m] moving at ``velocities``."""
    from ...analysis import kernel_velocity

    kv = kernel_velocity(positions=positions, velocities=velocities, points=mesh.points, R=R)
    writer.density_frame(t, mesh, point_data={"density": density, "velocity": kv})
