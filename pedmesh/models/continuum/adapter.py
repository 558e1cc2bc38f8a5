"""The continuum models behind the run protocol (:class:`MacroRun`), and their registry
entries (:func:`register_continuum_model`: one :class:`ContinuumEntry` per model, in the
one registry of :mod:`pedmesh.models.registry`)."""

from __future__ import annotations

import dataclasses
import math
import functools
from dataclasses import dataclass, fields
from typing import Any, Callable

import numpy as np
import shapely
import shapely.affinity

from ... import parameters as P
from ...analysis.evacuation import evacuation_times_from_curve
from ...errors import ParameterError, SimulationError
from ..registry import CONTINUUM, ModelEntry, get_model, register_model
from .base import MacroModel
from .fv_kernels import copy_cells
from .solver import FVController, FVOptions, FVSolver, FVState

__all__ = ["MacroRunOptions", "MacroRun", "ContinuumEntry", "register_continuum_model",
           "macro_model", "initial_density", "area_densities"]

#: [s] the step of the clock while every pedestrian is still within their premovement
WAIT_STEP = 0.5


@dataclass(frozen=True, kw_only=True)
class MacroRunOptions:
    """Output and stopping settings of a continuum run (declared in
    :mod:`pedmesh.parameters`): ``output_interval``, ``sample_interval``, ``empty_below``
    (the room counts as empty when fewer remain; t_evac_100 is that moment) and
    ``dense_frames`` (1: steps run freely and each frame is the linear interpolation in
    time of the two states around its time, conservative and positive like the states;
    0: steps are shortened to land on every frame time, about 8 % more steps at 1 s
    frames)."""

    output_interval: float = P.field("output_interval")
    sample_interval: float = P.field("sample_interval")
    empty_below: float = P.field("empty_below")
    dense_frames: int = P.field("dense_frames")

    def __post_init__(self) -> None:
        P.check_fields(self)


def initial_density(room, mesh) -> np.ndarray:
    """Cell averages [ped/m^2] of the room's start areas: each area's density (1/spacing^2,
    density, or count/area) times the covered fraction of every triangle."""
    return np.sum(area_densities(room, mesh), axis=0) if room.start_areas else \
        np.zeros(mesh.n_triangles)


def area_densities(room, mesh) -> list[np.ndarray]:
    """:func:`initial_density` of each start area separately (a list of (m,) arrays). A
    building's (``mesh`` its surface) are those of its levels' start areas, in order."""
    from ...geometry.site import is_building

    if is_building(room):
        return _building_area_densities(room, mesh)
    return _area_densities(room.start_areas, room.walkable, mesh.points, mesh)


def _building_area_densities(building, surface) -> list[np.ndarray]:
    from ...mesh.atlas import build_atlas

    atlas = build_atlas(surface)
    out = []
    for lv in building.levels:  # each level's start areas, moved to its place in the atlas
        dx, dy = atlas.level_shift(lv.name)
        walkable = shapely.affinity.translate(lv.room.walkable, dx, dy)
        areas = [moved_start_area(a, dx, dy) for a in lv.room.start_areas]
        out += _area_densities(areas, walkable, atlas.glued.points, atlas.glued)
    return out


def moved_start_area(a, dx: float, dy: float):
    """The start area ``a`` moved by (dx, dy) [m] (to a level's place in the atlas)."""
    return dataclasses.replace(a, polygon=[(x + dx, y + dy) for x, y in a.polygon])


def _area_densities(start_areas, walkable, points, mesh) -> list[np.ndarray]:
    out = []
    tris = shapely.polygons(points[mesh.triangles])
    for s in start_areas:
        rho = np.zeros(mesh.n_triangles)
        shape = s.shape.intersection(walkable)
        if s.spacing is not None:
            d = 1.0 / s.spacing**2
        elif s.density is not None:
            d = s.density
        else:
            d = s.count / shape.area
        cand = shapely.intersects(tris, shape)
        frac = np.zeros(mesh.n_triangles)
        frac[cand] = shapely.area(shapely.intersection(tris[cand], shape)) / mesh.areas[cand]
        rho += d * np.clip(frac, 0.0, 1.0)
        out.append(rho)
    return out


def _copy_state(Q: np.ndarray) -> np.ndarray:
    """A copy of the cell states ``Q`` (on the threads)."""
    if Q.ndim == 2 and Q.flags.c_contiguous:
        out = np.empty_like(Q)
        copy_cells(Q, out)
        return out
    return Q.copy()


def _is_surface(mesh) -> bool:
    from ...mesh.surface import SurfaceMesh

    return isinstance(mesh, SurfaceMesh)


def _split(overrides: dict[str, Any], targets: dict[str, set[str]]) -> dict[str, dict]:
    known = set().union(*targets.values())
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise ParameterError(f"unknown parameter '{unknown[0]}' "
                             f"(known: {', '.join(sorted(known))})")
    return {k: {n: v for n, v in overrides.items() if n in names} for k, names in targets.items()}


class MacroRun:
    """A finite-volume continuum model run through ``pedmesh run``."""

    def __init__(self, room, mesh, overrides: dict[str, Any], *, model: str,
                 rho0: np.ndarray | None = None) -> None:
        entry = get_model(model)
        if not isinstance(entry, ContinuumEntry):
            raise ParameterError(f"model '{model}' is not a continuum model")
        model_params = entry.model_parameters
        parts = _split(overrides, {
            "model": {p.name for p in model_params},
            "fv": {f.name for f in fields(FVOptions)},
            "run": {f.name for f in fields(MacroRunOptions)},
        })
        # every value is checked (FVOptions and MacroRunOptions check their own) before
        # anything is built
        self.fv_options = FVOptions(**parts["fv"])
        self.options = MacroRunOptions(**parts["run"])
        self.model = entry.physics(**P.check_values(parts["model"], model_params))
        self.name = entry.name
        #: the mesh the run reports on (a building's 3-D surface); the solver's is
        #: :attr:`fv_mesh` (a building's glued atlas, :mod:`pedmesh.mesh.atlas`)
        self.mesh = mesh
        self.atlas = None
        fv_mesh = mesh
        if _is_surface(mesh):
            from ...mesh.atlas import build_atlas

            if not entry.surface:
                raise ParameterError(f"model '{entry.name}' does not run on buildings (levels "
                                     "and stairs) yet; eos, rdue and pw do")
            self.atlas = build_atlas(mesh)
            fv_mesh = self.atlas.glued
        self.fv_mesh = fv_mesh
        #: things the user should know about this run (e.g. a calibration for other parameters)
        self.warnings = list(getattr(self.model, "warnings", []))
        from .solver import threading_layer, threading_note

        if threading_layer() != "tbb":  # (say what it costs: pedmesh._threads)
            self.warnings.append(threading_note())
        self.solver = FVSolver(fv_mesh, self.model, self.fv_options)
        #: start areas with a premovement time or arrivals (entrances): (their density (m,)
        #: [ped/m^2], the distribution or schedule, their number of people [ped]); their
        #: people appear where they stand, at rest, as its CDF grows (a delayed source)
        self._delayed: list[tuple[np.ndarray, Any, float]] = []
        if rho0 is None:
            if room is None or not room.start_areas:
                raise SimulationError("no initial crowd: the room has no start areas")
            parts = area_densities(room, mesh)
            rho0 = np.zeros(mesh.n_triangles)
            for a, rho_a in zip(room.start_areas, parts):
                # an entrance's people arrive by its schedule (the same delayed source)
                delay = a.arrivals if a.arrivals is not None else a.premovement
                if delay is None:
                    rho0 += rho_a
                else:
                    rho0 += rho_a * float(delay.cdf(0.0))
                    self._delayed.append((rho_a, delay, self.solver.mass(rho_a[:, None])))
            self._note_population(room)
        self.state = FVState(self.model.initial_state(rho0))
        self.controller = FVController(self.solver, self.state)
        self._n0 = self.solver.mass(self.state.Q) + self.waiting
        if self._n0 <= 0:
            raise SimulationError("the initial crowd is empty")
        self.sample_interval = self.options.sample_interval
        self.output_interval = self.options.output_interval
        self.max_mass_error = 0.0
        self._curve_t = [0.0]
        self._curve_n = [0.0]
        #: a building's stair use (:mod:`pedmesh.analysis.stairs`; None on a room)
        self.stair_use = None
        building = room if room is not None else getattr(mesh, "building", None)
        if self.atlas is not None and building is not None:
            self._set_stair_use(building)

    # ------------------------------------------------------------------ contract
    @property
    def t(self) -> float:
        return self.state.t

    @property
    def n_initial(self) -> float:
        return self._n0

    @property
    def evacuated(self) -> float:
        return float(self.state.outflow.sum())

    @property
    def remaining(self) -> float:
        """Pedestrians [ped] inside: walking, and still waiting out their premovement."""
        return self.solver.mass(self.state.Q) + self.waiting

    @property
    def waiting(self) -> float:
        """Pedestrians [ped] who have not started yet (premovement)."""
        t = self.state.t
        return float(sum(n * (1.0 - float(d.cdf(t))) for _, d, n in self._delayed))

    def _note_population(self, room) -> None:
        """Warnings for what a continuum model cannot represent of the start areas."""
        for a in room.start_areas:
            for key, what in (("speed", "one free speed U_f"), ("radius", "no body radii"),
                              ("exits", "the quickest route to any exit")):
                if getattr(a, key) is not None:
                    self.warnings.append(
                        f"start area '{a.name}': its '{key}' is not used; the continuum "
                        f"model has {what}")

    @property
    def done(self) -> bool:
        return self.remaining < self.options.empty_below

    def step(self, t_limit: float = math.inf) -> None:
        """One step that never passes ``t_limit`` [s] (the next time the driver records
        something): it ends exactly on ``t_limit`` where the CFL step would pass it, and
        one that would stop short of it by under a tenth of a step is halved so that no
        sliver of a step follows (see :meth:`FVController.advance`; steps are only ever
        shortened). ``math.inf`` (the default): the plain CFL step, bit for bit as before.
        A ``t_limit`` that is NaN or not after :attr:`t` is a ValueError."""
        Q = self.state.Q
        t0 = self.state.t
        if self._delayed and self.solver.mass(self.state.Q) <= 1e-12 * self._n0:
            # nobody walks yet (all within their premovement): only the clock moves, by at
            # most WAIT_STEP s (a step's release is applied at its end, to this very array:
            # the state before it is a copy)
            self._prev = (t0, _copy_state(Q))
            self.state.t = min(t_limit, t0 + WAIT_STEP)
        else:
            # the step puts a new array in state.Q and only reads this one (FVSolver.step;
            # a split source returns a new array too): the state before it needs no copy
            self._prev = (t0, Q)
            self.controller.advance(None if t_limit == math.inf else t_limit)
            if self.state.Q is Q:  # (a solver that stepped in place: the frames would be off)
                raise RuntimeError("the continuum step changed its state in place; the "
                                   "frames between steps need the state before it")
        if self._delayed:  # the people whose premovement ended within the step start, at rest
            t1 = self.state.t
            add = np.zeros(len(self.state.Q))
            for rho, d, _ in self._delayed:
                add += rho * float(d.cdf(t1) - d.cdf(t0))
            self.state.Q[:, 0] += add
            self.controller.mass0 += self.solver.mass(add[:, None])
        self.max_mass_error = max(self.max_mass_error, self.controller.mass_error)
        self._curve_t.append(self.state.t)
        self._curve_n.append(self.evacuated)

    def stepping(self):
        """A context for a run's steps (the run driver holds it around its loop): numba's
        threads and BLAS set once for all of them (:meth:`FVController.stepping`), the
        caller's settings back afterwards."""
        return self.controller.stepping()

    def outflow_rates(self) -> np.ndarray:
        """Flow [ped/s] through each exit in the last step."""
        return self.state.last_exit_flux

    def exit_counts(self) -> np.ndarray:
        """Pedestrians [ped] out through each exit so far (the integrated boundary flux)."""
        return np.array(self.state.outflow, float)

    def record(self, writer, final: bool = False) -> None:
        """On a building: the inflow through each stair's edges from the levels, integrated
        over every step (the trapezoid rule), and each sample interval the people on each
        stair (its mass) (:mod:`pedmesh.analysis.stairs`)."""
        if self.stair_use is None:
            return
        t = self.state.t
        Q = self.state.Q
        rho = Q[:, 0]
        if t >= self._next_stair_sample - 1e-9 or final:
            self._next_stair_sample = t + self.sample_interval
            mass = np.bincount(self.atlas.glued.piece, weights=rho * self.fv_mesh.areas,
                               minlength=len(self.mesh.pieces))
            self.stair_use.occupancy(t, mass)
        if self.model.n_vars == 1:
            vel = self.model.speed(rho)[:, None] * self.solver.e_cell
        else:
            vel = self.model.velocity(Q)
        t0, f0 = self._stair_flux
        f = np.zeros(len(self._stair_rows))
        q = rho[:, None] * vel
        for k, (across, nl, _, _) in enumerate(self._stair_rows):
            f[k] = np.sum(np.maximum(0.0, np.sum(q[across] * nl, axis=1)))
        if t > t0:
            for k, (_, _, stair, frm) in enumerate(self._stair_rows):
                self.stair_use.enter(t, stair, 0.5 * (f0[k] + f[k]) * (t - t0), frm)
        self._stair_flux = (t, f)

    def _set_stair_use(self, building) -> None:
        """The stair use's record and, per stair edge, the stair's cells along it and the
        edges' normals (out of the level, into the stair) times their lengths [m]: the
        inflow is the stair cells' momentum rho u through the edge, an estimate within 7 %
        (on the office eos, rdue and pw count 243.4, 231.6 and 240.1 of the 240 people who
        come down the first floor's two stairs; on tests/building_data.py's TWO 31.4, 28.0
        and 29.7 of 30; the level's cells, whose speed is not the stair's, or the mean of
        both sides count up to 38 % more or 7 % fewer)."""
        from scipy.spatial import cKDTree

        from ...analysis.stairs import StairUse

        self.stair_use = StairUse(self.mesh, building)
        op = self.atlas.open
        mid = op.points[op.edges].mean(axis=1)
        self._stair_rows = []
        for r in self.atlas.hinges:
            k, frm, to = int(r[0]), int(r[1]), int(r[2])
            if not self.stair_use.is_stair(to) or self.stair_use.is_stair(frm):
                continue
            e = op.exit_edges(k)
            back = [int(b[0]) for b in self.atlas.hinges
                    if int(b[1]) == to and int(b[2]) == frm]
            other = np.concatenate([op.exit_edges(b) for b in back])
            # the same edge on the stair's side: its midpoint carried over by the shift
            _, j = cKDTree(mid[other]).query(mid[e] + r[3:5])
            nl = op.edge_normals[e] * op.edge_lengths[e][:, None]
            self._stair_rows.append((op.edge_triangles[other[j], 0], nl, to, frm))
        self._stair_flux = (self.state.t, np.zeros(len(self._stair_rows)))
        self._next_stair_sample = self.state.t

    def parameters(self) -> dict[str, Any]:
        return {**self.model.parameters(), **dataclasses.asdict(self.fv_options),
                "cfl": self.solver.cfl, "exit": self.solver.exit_kind,
                "implicit_pressure": self.solver.implicit is not None,
                "stages": self.solver.stages,
                **dataclasses.asdict(self.options)}

    @property
    def dense_frames(self) -> bool:
        """Whether the driver lets steps run past frame times and asks for
        :meth:`write_frame_at` instead (MacroRunOptions.dense_frames)."""
        return bool(self.options.dense_frames)

    def state_at(self, t: float) -> np.ndarray:
        """The cell state at time ``t`` [s] within the last step: the linear interpolation
        in time of the states at its start and end (the current state at its end)."""
        t1, Q = self.state.t, self.state.Q
        prev = getattr(self, "_prev", None)
        if prev is None or t >= t1 or prev[0] >= t1:
            return Q
        t0, Q0 = prev
        if not t0 <= t:
            raise ValueError(f"t = {t!r} s is not within the last step [{t0}, {t1}] s")
        w = (t - t0) / (t1 - t0)
        return (1.0 - w) * Q0 + w * Q

    def cell_fields(self, Q: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Density [ped/m^2] and velocity [m/s] per cell (of the current state, or of
        ``Q``)."""
        if Q is None:
            Q = self.state.Q
        rho = Q[:, 0]
        if self.model.n_vars == 1:  # RDUE: u = U_e(rho) e
            speed = self.model.speed(rho)
            vel = speed[:, None] * self.solver.e_cell
        else:
            vel = self.model.velocity(Q)
        if self.atlas is not None:  # a building: the velocity in 3-D, along the surface
            vel = self.atlas.cell_vectors_3d(vel)
        return {"rho": rho, "velocity": vel}

    def write_frame(self, writer, frame: int) -> None:
        self.write_frame_at(writer, frame, self.state.t)

    def write_frame_at(self, writer, frame: int, t: float) -> None:
        """Write frame ``frame`` at time ``t`` [s] within the last step (see
        :meth:`state_at`)."""
        f = self.cell_fields(self.state_at(t))
        writer.density_frame(t, self.mesh, point_data={"phi": self.solver.phi},
                             cell_data={"rho": f["rho"], "velocity": f["velocity"]})

    def summary(self) -> dict[str, Any]:
        n0 = self._n0
        t = np.asarray(self._curve_t)
        e = np.asarray(self._curve_n)
        t50, t90 = evacuation_times_from_curve(t, e, n0, (0.5, 0.9))
        done = np.flatnonzero(n0 - e < self.options.empty_below)
        t100 = float(t[done[0]]) if len(done) else None
        return {
            "n_initial": n0,
            "n_evacuated": self.evacuated,
            "t_evac_50": t50,
            "t_evac_90": t90,
            "t_evac_100": t100,
            "steps": self.state.steps,
            "steps_retried": self.controller.retried,
            "dt": float(np.mean(np.diff(t))) if len(t) > 1 else None,
            "exits": {n: float(v) for n, v in zip(self.mesh.exit_names, self.state.outflow)},
            "mass_error_max": self.max_mass_error,
            "exit_condition": self.solver.exit_kind,
            **({"stairs": self.stair_use.summary()} if self.stair_use is not None else {}),
        }


# ---------------------------------------------------------------------- registration
#: the numerical and output parameters every continuum model takes
NUMERICS: tuple[P.Parameter, ...] = tuple(
    f.metadata["parameter"] for cls in (FVOptions, MacroRunOptions) for f in fields(cls))


#: the desired-speed law's parameters (:mod:`pedmesh.speed`)
SPEED_PARAMETERS = ("U_f", "beta", "speed_law", "rho_jam", "gamma_w", "rho_shift",
                    "speed_table")
#: the physical parameters of a model with momentum relaxed to the desired velocity
BASE_PARAMETERS = ("U_f", "beta", "tau", "rho_cut", "u_max") + SPEED_PARAMETERS[2:]
#: the social force model's Table 1 parameters a model derived from it takes
SFM_PARAMETERS = ("A", "B", "k", "kappa", "m", "r")


@dataclass(frozen=True)
class ContinuumEntry(ModelEntry):
    """A continuum model's registry entry: besides :class:`~pedmesh.models.ModelEntry`'s,
    ``physics(**parameters)``, the :class:`~pedmesh.models.continuum.base.MacroModel` the
    finite-volume core solves, and ``model_parameters``, those of its parameters that go
    to it (the others are the solver's and the run's: :data:`NUMERICS`)."""

    physics: Callable[..., MacroModel] | None = None
    model_parameters: tuple[P.Parameter, ...] = ()
    #: whether the model runs on a building's surface (levels and stairs)
    surface: bool = False


def register_continuum_model(name: str, physics: Callable[..., MacroModel],
                             parameters: tuple[str | P.Parameter, ...], *,
                             aliases: tuple[str, ...] = (), description: str = "",
                             replace: bool = False, surface: bool = False) -> ContinuumEntry:
    """Register the continuum model ``physics(**parameters) -> MacroModel`` under ``name``:
    ``parameters`` are its physical parameters (declarations, or the names of declared
    ones); every continuum model also takes the solver's and the run's (:data:`NUMERICS`).
    ``pedmesh run --model NAME`` then solves it with the finite-volume core; ``surface``:
    also on a building's surface (the model's fluxes and sources only read the
    desired direction, whose length is the stair's speed factor there)."""
    own = tuple(p if isinstance(p, P.Parameter) else P.get(p) for p in parameters)
    return register_model(ContinuumEntry(
        name=name, build=functools.partial(MacroRun, model=name), parameters=own + NUMERICS,
        scale=CONTINUUM, options=frozenset({"rho0"}), random=False, aliases=aliases,
        description=description, physics=physics, model_parameters=own, surface=surface),
        replace=replace)


def macro_model(name: str, **params) -> MacroModel:
    """The physics of continuum model ``name`` with the given parameters (the others at
    their defaults), as the finite-volume core solves it. Its values are checked against
    the declarations' bounds only, not their physical ranges (a run checks those first, see
    :mod:`pedmesh.parameters`), so that tests may switch a term off (``tau=1e30``)."""
    entry = get_model(name)
    if not isinstance(entry, ContinuumEntry):
        raise ParameterError(f"unknown continuum model '{name}'")
    return entry.physics(**params)
