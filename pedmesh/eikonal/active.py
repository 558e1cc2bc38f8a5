"""A building's routes re-solved only where the crowd can change them (issue 45).

The route cost of the crowd models is ``1/U_e(rho)`` at the vertices (times the walls' and
the stairs' and corners' factors): the cost at zero density wherever nobody is near. So a
potential ``phi0`` solved for the costs of the empty building (a *static* potential) is
the potential of the crowd's costs too below the level ``m`` where the first cost that
differs from the empty building's comes in: the fast march accepts the vertices in the
order of their values, and a vertex's value comes from vertices accepted before it, through
triangles and corner rays whose costs are the empty building's as long as its value is
below ``m``. :class:`ActiveRoutes` therefore takes ``phi0`` where it is below ``m`` (those
vertices accepted at once, in the static march's order) and marches only the rest
(:func:`~pedmesh.eikonal.fmm_kernels.march_from`): with the crowd on the top floor of a
tall building, that floor, not the building. The results are those of the whole march,
bit for bit, whatever the costs (a cost below the empty building's only lowers ``m``; the
speed laws of :mod:`pedmesh.speed` never give one): the march breaks ties by vertex number
(:attr:`~pedmesh.eikonal.surface.SurfaceEikonalSolver.ordered`), so its order is a function
of its costs alone.

Which way a stair is walked comes from the previous solve's potential, as in
:meth:`~pedmesh.eikonal.surface.BuildingRoutes.solve` (the first solve's from the
distance), so the empty building's solves follow a chain, each with the stair factors of
the one before, which ends in a fixed point or a cycle (on a tall building of the issue's
kind a few triangles along each stair's side walls are walked up in one solve and down in
the next: a cycle of two). The chain's solves are the static potentials
(:class:`_Phase`), each the reference of the crowd's solves in turn: the n-th solve's
stairs are walked as the n-th static solve's, but near the crowd. (Without a cycle within
:data:`MAX_STATIC_SOLVES` solves the last one stays the reference, and the triangles whose
factors differ from its own count as changed in every solve: still exact.)

The steering table (the direction field's packed table scaled by the stair speed factors,
:func:`~pedmesh.eikonal.surface.atlas_direction_field`,
:func:`~pedmesh.eikonal.direction.scale_packed`) is kept and brought up to date a flat
group of pieces (a *unit*: a level or a stair, or levels joined by flat connectors) at a
time, each row as the whole computation computes it, and only where it is read: a solve
marks the units whose rows its potential changed, and :meth:`ActiveRoutes.refresh` brings
those up to date that the caller names (the social force model: the units people stand
on and those across their stair edges, after a solve and after someone crosses onto
another piece). The others keep an earlier potential's rows until someone comes.

:data:`ACTIVE_SET` switches this off: the social force model then solves the whole
building every time (:meth:`~pedmesh.eikonal.surface.BuildingRoutes.solve`), the
reference the tests compare with.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from .._arrays import readonly
from ..mesh.triangle_mesh import csr_ranges
from . import fmm_kernels as _fmm
from .direction import (PACK_WIDTH, _basis_gradients, _descent, _jamb_overrides, _pack,
                        _wall_normals, scale_packed, vertex_directions)
from .fmm import _check_cost
from .surface import (BuildingRoutes, _hinge_edge_rows, _hinge_inner_vertices, _hinge_rings,
                      _jamb_rows, _stair_speeds, atlas_direction_field, hinge_inner_directions,
                      hinge_jambs, inflow_hinges, stair_factors)

__all__ = ["ACTIVE_SET", "ActiveRoutes", "MAX_STATIC_SOLVES"]

#: re-solve a building's routes only where the crowd can change them
#: (:class:`ActiveRoutes`); False: the whole building at every solve (the reference)
ACTIVE_SET = True
#: the most solves of the empty building looking for its chain's cycle
MAX_STATIC_SOLVES = 8

_NONE = np.zeros(0, np.int64)
_NO_ROWS = np.zeros(1, np.int64)  # (the CSR pointer of no rows)


def _csr(keys: np.ndarray, values: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``values`` grouped by ``keys`` in [0, n) (stable): CSR ``(ptr, values)``."""
    order = np.argsort(keys, kind="stable")
    ptr = np.zeros(n + 1, np.int64)
    np.cumsum(np.bincount(keys, minlength=n), out=ptr[1:])
    return ptr, np.ascontiguousarray(np.asarray(values)[order])


@nb.njit(cache=True, nogil=True)
def _distinct(ptr, idx, keys, extra, mark):
    """The distinct entries, sorted, of the CSR rows ``keys`` (of ``ptr``, ``idx``) and of
    ``extra``; ``mark`` (bool over their range, all False) is left as it was."""
    total = extra.shape[0]
    for k in keys:
        total += ptr[k + 1] - ptr[k]
    out = np.empty(total, np.int64)
    c = 0
    for k in keys:
        for a in range(ptr[k], ptr[k + 1]):
            v = idx[a]
            if not mark[v]:
                mark[v] = True
                out[c] = v
                c += 1
    for v in extra:
        if not mark[v]:
            mark[v] = True
            out[c] = v
            c += 1
    out = np.sort(out[:c])
    for v in out:
        mark[v] = False
    return out


class _Phase:
    """One static potential ``phi`` of the empty building (:mod:`pedmesh.eikonal.active`):
    solved with the stair factors ``F`` (m,), its triangle and corner ray costs ``f``,
    ``r``, its own stair factors ``fphi``, the order its march accepted the vertices in
    (``order``; ``rank``: each vertex's place in it, ``UNRANKED`` if never) and ``pmax``
    (the largest value among the first k + 1 accepted)."""

    def __init__(self, routes: BuildingRoutes, c_tri: np.ndarray, F: np.ndarray) -> None:
        sv, s = routes.solver, routes.surface
        self.F = F
        f = np.broadcast_to(c_tri, (s.n_triangles,)) / F * routes.corner_cost
        self.f, self.r = sv._costs(np.ascontiguousarray(f))
        self.phi = np.empty(s.n_points)
        order = np.empty(s.n_points, np.int32)
        cnt = _fmm.march(self.phi, sv.fixed_vertices, sv._exit_values(None), sv.pts,
                         sv.vt_ptr, sv.vt_corner, sv.ds_ptr, sv.ds_corner, sv.ray_ptr,
                         sv.ray_idx, self.r, self.f, True, order)
        self.fphi = stair_factors(s, self.phi)
        self.order = np.ascontiguousarray(order[:cnt])
        self.rank = np.full(s.n_points, _fmm.UNRANKED, np.int32)
        self.rank[self.order] = np.arange(cnt, dtype=np.int32)
        self.pmax = np.maximum.accumulate(self.phi[self.order])


class ActiveRoutes:
    """The routes of :class:`~pedmesh.eikonal.surface.BuildingRoutes` ``routes`` for costs
    that differ from ``vertex_cost`` (n,) [s/m] (the surface vertices' costs at zero
    density, before the stairs' and corners' factors) at a few vertices: :meth:`route`,
    with the steering table kept in rows ``offset ... offset + m - 1`` of ``table`` (an
    array of PACK_WIDTH columns, e.g. a stack of several route groups' tables; else one of
    its own: :attr:`table`). (Not a view of the stack: a copy of the model, pickled or
    deep-copied, keeps its routes writing into its own stack.)"""

    def __init__(self, routes: BuildingRoutes, vertex_cost: np.ndarray,
                 table: np.ndarray | None = None, offset: int = 0) -> None:
        self.routes = routes
        self.atlas = routes.atlas
        s = self.surface = routes.surface
        sv = self.solver = routes.solver
        self.cost_v0 = np.array(vertex_cost, float)
        self._cv = self.cost_v0.copy()  # (the vertex costs, set and put back in route)
        c_tri = self.cost_v0[s.triangles].mean(axis=1)
        # the empty building's chain of solves from the distance (where BuildingRoutes.solve
        # starts) to its first repeat
        F = stair_factors(s, sv.solve(1.0))
        chain: list[_Phase] = []
        start = None
        for _ in range(MAX_STATIC_SOLVES):
            start = next((k for k, p in enumerate(chain) if np.array_equal(p.F, F)), None)
            if start is not None:
                break
            chain.append(_Phase(routes, c_tri, F))
            F = chain[-1].fphi
        #: the static potentials: the chain's solves, the references of the solves in turn
        self.phases = chain
        #: the phase after each (after the last: its cycle's first, or itself)
        self._succ = list(range(1, len(chain))) + [len(chain) - 1 if start is None
                                                    else start]
        #: per phase: the stair triangles whose factors from its potential are not those
        #: the next phase is solved with (none but in the last phase without a cycle)
        self._bad = [np.flatnonzero(p.fphi != chain[self._succ[k]].F)
                     for k, p in enumerate(chain)]
        self.walked = _stair_speeds(s)[0]
        self._marks: dict[int, np.ndarray] = {}  # (for _union)
        self._deltas: dict[tuple, np.ndarray] = {}  # (for _delta)
        # the state after the last solve: its reference; the stair triangles whose
        # factors from its potential are not those the next reference is solved with
        # (triangles, factors); the current triangle and ray costs; the triangles and
        # rays whose costs were not the reference's, the potential and the vertices
        # where it may differ from its reference's (none before the first solve: phase 0)
        self._phase, self._last = 0, 0
        self._fd = (_NONE, np.zeros(0))
        self._f, self._r = chain[0].f.copy(), chain[0].r.copy()
        self._changed_tris, self._ray_set = _NONE, _NONE
        self._phi, self._marched = chain[0].phi, _NONE
        self._set_maps()
        self._set_steering(table, offset)
        for k, nxt in enumerate(self._succ):  # (what changes from a phase to the next)
            for what in ("f", "r"):
                self._delta(what, k, nxt)
            self._delta_units(k, nxt)
        #: the number of vertices marched by the last :meth:`route` (the active set)
        self.last_marched = 0

    # ------------------------------------------------------------------ set-up
    def _set_maps(self) -> None:
        """The adjacency :meth:`route` follows: the vertices that offer each vertex an
        update through a split row or a corner ray (for
        :func:`~pedmesh.eikonal.fmm_kernels.march_from`), and the corner rays of each flat
        group (a ray's cost is its group's triangles')."""
        sv, s = self.solver, self.surface
        n = s.n_points
        d_of = np.repeat(np.arange(n), np.diff(sv.ds_ptr))
        src = np.repeat(np.arange(n), np.diff(sv.ray_ptr))
        keys = np.concatenate([sv.ds_corner[:, 1].astype(np.int64),
                               sv.ray_idx.astype(np.int64)])
        self.rev_ptr, rev = _csr(keys, np.concatenate([d_of, src]), n)
        self.rev_idx = rev.astype(np.int32)
        self.ray_src = src
        # march_from's work arrays
        self._pos = np.full(n, _fmm.ACCEPTED, np.int32)
        self._fixed = np.zeros(n, bool)
        self._fixed[sv.fixed_vertices] = True
        self.nz = np.diff(sv.ray_samp_ptr)
        self.tri_group = s.piece_group[s.piece]  # (m,) each triangle's flat group
        ng = int(self.tri_group.max()) + 1
        rg = self.tri_group[sv.ray_samp_tri[sv.ray_samp_ptr[:-1]]]  # (a ray is in one)
        # each group's rays as runs of consecutive rays: (first, end) CSR by group
        first = np.flatnonzero(np.diff(np.concatenate([[-1], rg])) != 0)
        end = np.concatenate([first[1:], [len(rg)]])[:len(first)]
        self.group_runs = _csr(rg[first], np.stack([first, end], axis=1).reshape(-1, 2), ng)
        #: the vertices of a stair walked at its speeds (whose triangles' factors can change)
        self.on_stair = np.zeros(s.n_points, bool)
        self.on_stair[s.triangles[_stair_speeds(s)[0]].ravel()] = True

    def _set_steering(self, table: np.ndarray | None, offset: int) -> None:
        """The direction field and steering table of the first phase's potential (kept in
        ``table`` from row ``offset``), and per flat group
        (:attr:`~pedmesh.mesh.surface.SurfaceMesh.piece_group`, the *units* of
        :meth:`refresh`): its triangles, its atlas vertices,
        the triangles whose gradients its rows read, its vertices along stair edges, its
        jamb and stair edge rows, and the groups across its stair edges."""
        atlas, s = self.atlas, self.surface
        p0 = self.phases[0]
        df = atlas_direction_field(atlas, p0.phi)
        P = scale_packed(df.packed, p0.fphi)
        if table is None:
            table, offset = P, 0
        else:
            table[offset:offset + len(P)] = P
        #: the stack the steering table is kept in, and its first row there
        self.stack, self.offset = table, offset
        self.G, self.TD = df.triangle_gradients, df.triangle_directions
        self.VD = df.vertex_directions
        st = atlas.steer
        self.bgrad = _basis_gradients(st)
        self.wall_n, self.jamb = _wall_normals(st), _jamb_overrides(st)
        self.finite_a = np.isfinite(p0.phi[atlas.to_surface])  # (where an exit is reached)
        self.s2a = _csr(atlas.to_surface, np.arange(len(atlas.to_surface)), s.n_points)
        self.merged = atlas.flat_steer
        if self.merged is not None:
            mesh, key = self.merged
            self.finite_m = np.zeros(mesh.n_points, bool)
            self.finite_m[key] = self.finite_a
        # the units
        unit = self.tri_group
        nu = int(unit.max()) + 1
        self.unit_tris = _csr(unit, np.arange(len(unit)), nu)
        vunit = np.empty(st.n_points, np.int64)
        vunit[st.triangles.ravel()] = np.repeat(unit, 3)
        self.vert_unit = vunit
        self.unit_verts = _csr(vunit, np.arange(st.n_points), nu)
        self.hv = _hinge_inner_vertices(atlas)
        ring, rptr = _hinge_rings(atlas)
        self.unit_hinge = _csr(vunit[self.hv], np.arange(len(self.hv)), nu)
        self.jr = _jamb_rows(atlas)
        self.unit_jambs = _csr(unit[self.jr[:, 0]], np.arange(len(self.jr)), nu)
        _, he_tri, _, across = _hinge_edge_rows(atlas)
        self.unit_inflow = _csr(unit[he_tri], np.arange(len(he_tri)), nu)
        # the gradients a unit's rows read: its own triangles', the rings of its vertices
        # along stair edges (both sides) and the triangles across its stair edges
        hu = np.repeat(vunit[self.hv], np.diff(rptr))
        keys = np.concatenate([unit, hu, unit[he_tri]])
        self.unit_reads = _csr(keys, np.concatenate([np.arange(len(unit)), ring, across]),
                               nu)
        #: the units that read each triangle's gradient
        self.tri_readers = _csr(self.unit_reads[1], np.repeat(np.arange(nu), np.diff(
            self.unit_reads[0])), s.n_triangles)
        h = atlas.hinges
        pu = s.piece_group[h[:, 1:3].astype(np.int64)]  # (the groups on either side)
        self.unit_next = _csr(np.concatenate([pu[:, 0], pu[:, 1]]),
                              np.concatenate([pu[:, 1], pu[:, 0]]), nu)
        #: the units whose rows may not be those of the last potential
        self.dirty = np.zeros(nu, bool)

    # ------------------------------------------------------------------ helpers
    def _mark(self, size: int) -> np.ndarray:
        """A bool work array over [0, size), all False (put back so after use)."""
        mark = self._marks.get(size)
        if mark is None:
            mark = self._marks[size] = np.zeros(size, bool)
        return mark

    def _union(self, size: int, *arrays: np.ndarray, rows=None) -> np.ndarray:
        """The distinct entries, sorted, of ``arrays`` and of the CSR rows ``rows`` =
        ``(ptr, idx, keys)`` (all in [0, size))."""
        extra = np.concatenate([np.asarray(a, np.int64) for a in arrays]) if arrays else _NONE
        ptr, idx, keys = rows if rows is not None else (_NO_ROWS, _NONE, _NONE)
        return _distinct(ptr, idx, np.asarray(keys, np.int64), extra, self._mark(size))

    def _delta(self, what: str, a: int, b: int) -> np.ndarray:
        """Where phases ``a`` and ``b`` differ in ``what`` ("phi": the vertices, "f": the
        triangles' costs, "r": the corner rays' costs)."""
        if a == b:
            return _NONE
        key = (what, a, b)
        if key not in self._deltas:
            pa, pb = self.phases[a], self.phases[b]
            self._deltas[key] = np.flatnonzero(getattr(pa, what) != getattr(pb, what))
        return self._deltas[key]

    # ------------------------------------------------------------------ a solve
    def route(self, vertices: np.ndarray, costs: np.ndarray) -> np.ndarray:
        """The potential (surface vertices) for the vertex costs of the empty building but
        ``costs`` at ``vertices`` (distinct surface vertices), as
        :meth:`~pedmesh.eikonal.surface.BuildingRoutes.solve` gives it after the same
        solves before; the steering table (``table``: that solve's direction field's
        packed table, scaled by its stair factors) is brought up to date where
        :meth:`refresh` is asked to."""
        s, sv = self.surface, self.solver
        ref = self.phases[self._phase]
        vertices = np.asarray(vertices, np.int64)
        costs = np.asarray(costs, float)
        # the triangles whose costs may not be the reference's: near the vertices whose
        # costs changed, and where the previous potential walks a stair otherwise
        cv = self._cv
        cv[vertices] = costs
        fd_t, fd_f = self._fd
        cand = self._union(s.n_triangles, fd_t, rows=(
            *s.vertex_triangles, vertices[costs != self.cost_v0[vertices]]))
        fac = ref.F[cand]
        fac[np.searchsorted(cand, fd_t)] = fd_f
        c_tri = cv[s.triangles[cand]].mean(axis=1)
        cv[vertices] = self.cost_v0[vertices]
        f_cand = c_tri / fac * self.routes.corner_cost[cand]
        _check_cost(f_cand)  # (as the whole solve checks them)
        diff = f_cand != ref.f[cand]
        ct = cand[diff]
        f = self._f  # (the last solve's: back to the reference's, then this one's)
        back = np.concatenate([self._changed_tris, self._delta("f", self._last,
                                                               self._phase)])
        f[back] = ref.f[back]
        f[ct] = f_cand[diff]
        self._changed_tris = ct
        rays = self._update_rays(ct, ref)
        # m: below it every value is the reference's
        lim = np.inf
        if len(ct):
            lim = float(ref.phi[s.triangles[ct]].min())
        if len(rays):
            lim = min(lim, float(np.min(ref.phi[self.ray_src[rays]]
                                         + np.minimum(self._r[rays], ref.r[rays]))))
        k0 = int(np.searchsorted(ref.pmax, lim, side="left"))
        if len(sv.fixed_vertices) and int(ref.rank[sv.fixed_vertices].max()) >= k0:
            k0 = 0  # (an exit's value not below m: the whole march)
        phi = np.empty(s.n_points)
        if k0 == 0:
            _fmm.march(phi, sv.fixed_vertices, sv._exit_values(None), sv.pts, sv.vt_ptr,
                       sv.vt_corner, sv.ds_ptr, sv.ds_corner, sv.ray_ptr, sv.ray_idx,
                       self._r, f, True, np.empty(0, np.int32))
            marched = np.arange(s.n_points)
        else:
            _fmm.march_from(phi, ref.phi, ref.rank, ref.order, k0, self._pos, self._fixed,
                            self._mark(s.n_points), self.rev_ptr, self.rev_idx, sv.pts,
                            sv.vt_ptr, sv.vt_corner, sv.ds_ptr, sv.ds_corner, sv.ray_ptr,
                            sv.ray_idx, self._r, f, np.empty(0, np.int32))
            marched = ref.order[k0:]
        self.last_marched = len(marched)
        # where the potential is not the reference's (the next solve's stairs), and where
        # it is not the last solve's (the steering table's rows to bring up to date)
        moved = marched[phi[marched] != ref.phi[marched]]
        near = self._union(s.n_points, marched, self._marched)
        self._mark_dirty(near[phi[near] != self._phi[near]])
        self.dirty[self._delta_units(self._last, self._phase)] = True
        # the next solve's reference, and the stairs walked otherwise than it is solved with
        st = self._union(s.n_triangles, rows=(*s.vertex_triangles, moved[self.on_stair[moved]]))
        st = st[self.walked[st]]
        nxt = self._succ[self._phase]
        tri = self._union(s.n_triangles, st, self._bad[self._phase])
        ft = ref.fphi[tri]
        ft[np.searchsorted(tri, st)] = stair_factors(s, phi, st)
        off = ft != self.phases[nxt].F[tri]
        self._fd = (tri[off], ft[off])
        self._phi, self._marched = phi, marched
        self._last, self._phase = self._phase, nxt
        return phi

    def _update_rays(self, ct: np.ndarray, ref: _Phase) -> np.ndarray:
        """The costs of the corner rays of the flat groups with a changed triangle ``ct``
        (the others at the reference's); returns the rays whose cost is not the
        reference's."""
        sv = self.solver
        r = self._r
        back = np.concatenate([self._ray_set, self._delta("r", self._last, self._phase)])
        r[back] = ref.r[back]
        gptr, runs = self.group_runs
        groups = self._union(len(gptr) - 1, self.tri_group[ct])
        runs = runs[csr_ranges(gptr[groups], gptr[groups + 1] - gptr[groups])]
        rays = csr_ranges(runs[:, 0], runs[:, 1] - runs[:, 0])
        self._ray_set = rays
        if len(rays) == 0:
            return rays
        sp = sv.ray_samp_ptr
        samp = self._f[np.concatenate([sv.ray_samp_tri[sp[a]:sp[b]] for a, b in runs])]
        nz = self.nz[rays]
        starts = np.concatenate([[0], np.cumsum(nz)[:-1]])
        r[rays] = np.add.reduceat(samp, starts) * (sv.ray_len[rays] / nz)
        return rays[r[rays] != ref.r[rays]]

    def _units_of(self, vertices: np.ndarray) -> np.ndarray:
        """The units whose rows change with the potential at the surface vertices
        ``vertices``: those that read the gradient of a triangle of theirs (a unit's own
        triangles, and those on the other side of its stair edges)."""
        if len(vertices) == 0:
            return _NONE
        s2a_ptr, s2a_idx = self.s2a
        da = s2a_idx[csr_ranges(s2a_ptr[vertices], s2a_ptr[vertices + 1] - s2a_ptr[vertices])]
        st = self.atlas.steer
        t1 = self._union(st.n_triangles, rows=(*st.vertex_triangles, da))
        return self._union(len(self.dirty), rows=(*self.tri_readers, t1))

    def _mark_dirty(self, changed: np.ndarray) -> None:
        """Mark the units whose rows change with the potential at the surface vertices
        ``changed`` (:meth:`_units_of`)."""
        self.dirty[self._units_of(changed)] = True

    def _delta_units(self, a: int, b: int) -> np.ndarray:
        """The units whose rows differ between the potentials of phases ``a`` and ``b``."""
        key = ("units", a, b)
        if key not in self._deltas:
            self._deltas[key] = self._units_of(self._delta("phi", a, b))
        return self._deltas[key]

    def units_near(self, triangles: np.ndarray) -> np.ndarray:
        """The units of ``triangles`` (e.g. those people stand on) and the units across
        their stair edges: where those people can be, or look, before they cross an edge
        (one step crosses at most one)."""
        nu = len(self.dirty)
        units = self._union(nu, self.tri_group[np.asarray(triangles, np.int64)])
        return self._union(nu, units, rows=(*self.unit_next, units))

    @property
    def table(self) -> np.ndarray:
        """(m, PACK_WIDTH) the steering table (a view of its rows in :attr:`stack`)."""
        return self.stack[self.offset:self.offset + self.atlas.steer.n_triangles]

    def _averaging(self, units: np.ndarray):
        """``(vertices, merged vertices, rows)``: the atlas vertices of ``units``, their
        vertices in :attr:`~pedmesh.mesh.atlas.Atlas.flat_steer`'s mesh (None without a
        flat connector) and the rows of those vertices (those of the steering mesh, or the
        merged ones) of the vertex averaging (:func:`~pedmesh.eikonal.direction.
        vertex_directions`), kept for the last few sets of units asked for (the crowd
        stays on the same pieces for a while)."""
        from .direction import _vertex_averaging

        key = units.tobytes()
        cache = self.__dict__.setdefault("_averaging_cache", {})
        if key not in cache:
            st = self.atlas.steer
            verts = self._union(st.n_points, rows=(*self.unit_verts, units))
            if self.merged is None:
                cache[key] = (verts, None, _vertex_averaging(st)[verts])
            else:
                mesh, k = self.merged
                mv = np.unique(k[verts])
                cache[key] = (verts, mv, _vertex_averaging(mesh)[mv])
            while len(cache) > 8:
                cache.pop(next(iter(cache)))
        return cache[key]

    def refresh(self, units: np.ndarray | None = None) -> None:
        """Bring the steering table's rows of the ``units`` (all by default) to the last
        potential's (the direction field and stair factors of
        :meth:`~pedmesh.eikonal.surface.BuildingRoutes.solve`, row by row as it computes
        them); rows of other units may be those of an earlier potential until then."""
        atlas, st = self.atlas, self.atlas.steer
        units = np.flatnonzero(self.dirty) if units is None else np.asarray(units, np.int64)
        units = units[self.dirty[units]]
        if len(units) == 0:
            return
        phi = self._phi
        rows = self._union(st.n_triangles, rows=(*self.unit_tris, units))
        reads = self._union(st.n_triangles, rows=(*self.unit_reads, units))
        g, u = np.empty((len(reads), 2)), np.empty((len(reads), 2))
        _descent(self.bgrad[reads], readonly(self.surface.triangles[reads]), phi, g, u)
        self.G[reads], self.TD[reads] = g, u
        verts, mv, M = self._averaging(units)
        if self.merged is None:
            self.VD[verts] = vertex_directions(st, self.G, self.finite_a, verts, M)
        else:  # (a flat group is one unit: its merged vertices are all its own)
            mesh, key = self.merged
            self.VD[verts] = vertex_directions(mesh, self.G, self.finite_m, mv, M)[
                np.searchsorted(mv, key[verts])]
        h = self._union(len(self.hv), rows=(*self.unit_hinge, units))
        if len(h):
            hv = self.hv[h]
            self.VD[hv] = hinge_inner_directions(atlas, self.G, self.finite_a[hv], h)
        out = np.empty((len(rows), PACK_WIDTH))
        _pack(st.points, readonly(st.triangles[rows]), self.VD, self.TD[rows], self.wall_n[rows],
              self.jamb[rows], out)
        out[:, 20] = stair_factors(self.surface, phi, rows)
        jsel = self._union(len(self.jr), rows=(*self.unit_jambs, units))
        hsel = self._union(len(self.unit_inflow[1]), rows=(*self.unit_inflow, units))
        for t, col, val in (hinge_jambs(atlas, phi[atlas.to_surface[self.jr[jsel, 2]]],
                                        phi[atlas.to_surface[self.jr[jsel, 3]]], jsel),
                            inflow_hinges(atlas, self.TD, hsel)):
            k = np.searchsorted(rows, t)
            out[k, col], out[k, col + 1] = val[:, 0], val[:, 1]
        self.stack[self.offset + rows] = out
        self.dirty[units] = False
