"""The interface between the hybrid model's agents and its continuum, exact in count.

The continuum runs on the triangles outside the agent zone (:func:`split_mesh`), as a mesh
of its own: each edge between a continuum triangle and an agent triangle becomes an exit
of that mesh with an owner of its own (named ``iface-<j>``), after the room's own exits.
The finite-volume solver already integrates the mass through every exit edge into its
per-exit outflow (``FVState.outflow``), to round-off, so the people the continuum hands
to the agents are counted per interface edge with no change to the solver: the part of
``outflow`` after the room's exits (:meth:`ContinuumPart.interface_outflow`). What goes the
other way, an agent who walks into a continuum cell, is added to that cell's mass and
momentum by :func:`deposit`.

Every person is then in exactly one place: a continuum cell, an agent, an interface
edge's account (the mass that crossed and has not yet become an agent), or out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import ParameterError
from ...mesh.triangle_mesh import BoundaryKind, TriMesh

__all__ = ["ContinuumPart", "split_mesh", "deposit", "INTERFACE_PREFIX"]

#: the name of interface edge j as an exit of the continuum's mesh: INTERFACE_PREFIX + str(j)
INTERFACE_PREFIX = "iface-"


@dataclass(frozen=True)
class ContinuumPart:
    """The continuum's part of a mesh split by :func:`split_mesh`.

    ``mesh``: the continuum's sub-mesh (its exits: the parent's, same numbers and names,
    then one per interface edge); ``n_parent``: the parent's number of triangles;
    ``cells`` (m_c,): the parent triangle of each of its
    triangles; ``vertices`` (n_c,): the parent vertex of each of its vertices;
    ``n_exits``: how many exits the parent has; ``interface`` (k,): the parent edge of
    interface exit ``n_exits + j``; ``interface_cell`` (k,): the continuum triangle (of
    ``mesh``) on that edge; ``interface_agent_cell`` (k,): the parent triangle on the
    agents' side."""

    mesh: TriMesh
    n_parent: int
    cells: np.ndarray
    vertices: np.ndarray
    n_exits: int
    interface: np.ndarray
    interface_cell: np.ndarray
    interface_agent_cell: np.ndarray

    @property
    def n_interface(self) -> int:
        """Number of interface edges."""
        return len(self.interface)

    def exit_outflow(self, outflow: np.ndarray) -> np.ndarray:
        """The part of a per-exit outflow array of :attr:`mesh` (e.g. ``FVState.outflow``
        [ped]) through the room's own exits."""
        return np.asarray(outflow)[:self.n_exits]

    def interface_outflow(self, outflow: np.ndarray) -> np.ndarray:
        """The part of a per-exit outflow array of :attr:`mesh` through each interface edge
        (k,), in the order of :attr:`interface`."""
        return np.asarray(outflow)[self.n_exits:self.n_exits + self.n_interface]

    def to_parent(self, values: np.ndarray, fill: float = 0.0) -> np.ndarray:
        """Per-triangle ``values`` of :attr:`mesh` (m_c, ...) as an array over the parent's
        triangles, ``fill`` in the agent zone."""
        values = np.asarray(values)
        if len(values) != len(self.cells):
            raise ParameterError(f"{len(values)} values for the continuum's "
                                 f"{len(self.cells)} triangles")
        out = np.full((self.n_parent,) + values.shape[1:], fill, dtype=values.dtype)
        out[self.cells] = values
        return out


def split_mesh(mesh: TriMesh, agents: np.ndarray) -> ContinuumPart:
    """The continuum's part of ``mesh`` when the triangles ``agents`` ((m,) bool) belong to
    the agents (see the module docstring). The sub-mesh keeps the parent's walls,
    obstacles and exits where they bound a continuum triangle; an exit wholly inside the
    agent zone keeps its number and name with no edges."""
    if type(mesh) is not TriMesh:  # (a building's glued mesh: its atlas would be lost)
        raise ParameterError(f"the hybrid interface splits a room's mesh only, not a "
                             f"{type(mesh).__name__} (a building's)")
    agents = np.asarray(agents, bool).ravel()
    m = mesh.n_triangles
    if agents.shape != (m,):
        raise ParameterError(f"agents must be one flag per triangle ({m}), got {agents.shape}")
    if agents.all():
        raise ParameterError("the agent zone covers the whole mesh: nothing is left to the "
                             "continuum")
    cells = np.flatnonzero(~agents)
    tri = mesh.triangles[cells]
    vertices, local = np.unique(tri, return_inverse=True)
    tri = local.reshape(-1, 3)
    sub_of_parent = np.full(m, -1, np.int64)
    sub_of_parent[cells] = np.arange(len(cells))
    e2t = mesh.edge_triangles
    left, right = e2t[:, 0], e2t[:, 1]
    # the parent's tagged boundary edges (obstacles and exits) on continuum triangles
    tagged = (right < 0) & ~agents[left] & (mesh.edge_kind != BoundaryKind.WALL)
    # the interface: interior edges with one triangle on each side
    interior = right >= 0
    iface = np.flatnonzero(interior & (agents[left] != agents[np.where(interior, right, 0)]))
    n_exits = len(mesh.exit_names)
    on_left = ~agents[left[iface]]  # the continuum triangle is the edge's first
    cont = np.where(on_left, left[iface], right[iface])
    agent_side = np.where(on_left, right[iface], left[iface])
    g2l = np.full(mesh.n_points, -1, np.int64)
    g2l[vertices] = np.arange(len(vertices))
    t = np.flatnonzero(tagged)
    segments = np.concatenate([g2l[mesh.edges[t]], g2l[mesh.edges[iface]]])
    kind = np.concatenate([mesh.edge_kind[t],
                           np.full(len(iface), BoundaryKind.EXIT, np.int8)]).astype(np.int8)
    owner = np.concatenate([mesh.edge_owner[t], n_exits + np.arange(len(iface))])
    names = tuple(mesh.exit_names) + tuple(f"{INTERFACE_PREFIX}{j}" for j in range(len(iface)))
    sub = TriMesh(mesh.points[vertices], tri, segments, kind, owner, exit_names=names,
                  obstacle_names=mesh.obstacle_names)
    return ContinuumPart(mesh=sub, n_parent=m, cells=cells, vertices=vertices,
                         n_exits=n_exits, interface=iface, interface_cell=sub_of_parent[cont],
                         interface_agent_cell=agent_side)


def deposit(Q: np.ndarray, areas: np.ndarray, cell: int, mass: float,
            velocity: tuple[float, float] = (0.0, 0.0)) -> None:
    """Add ``mass`` [ped] walking at ``velocity`` [m/s] to continuum cell ``cell`` of the
    state ``Q`` (m_c, 1 or 3: density [ped/m^2] and, with three columns, momentum
    [ped/(m s)]) whose cells have ``areas`` [m^2]: the density rises by mass / area, the
    momentum by mass velocity / area, so that the cell's people and their momentum grow by
    exactly the agent's."""
    if not (np.isfinite(mass) and mass >= 0):
        raise ParameterError(f"an agent's mass must be >= 0, got {mass!r}")
    a = float(areas[cell])
    Q[cell, 0] += mass / a
    if Q.shape[1] >= 3:
        Q[cell, 1] += mass * float(velocity[0]) / a
        Q[cell, 2] += mass * float(velocity[1]) / a
