"""Matplotlib figures of rooms, meshes, routes, crowds and comparisons (imported lazily)."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_room", "plot_mesh", "plot_route", "plot_density", "plot_crowd",
           "plot_evacuation", "plot_outflow", "plot_fundamental"]


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def plot_room(ax, room, *, exit_color="tab:green", lw=1.2):
    """Walls, obstacles (grey) and exits (green) of a room."""
    from matplotlib.patches import Polygon as MplPolygon

    out = np.asarray(room.outline + (room.outline[0],))
    ax.plot(out[:, 0], out[:, 1], "k-", lw=lw)
    for o in room.obstacles:
        ax.add_patch(MplPolygon(np.asarray(o.polygon), closed=True, fc="0.6", ec="k", lw=lw))
    for k in range(len(room.exits)):
        e = np.asarray(room.exit_polyline(k))
        ax.plot(e[:, 0], e[:, 1], "-", color=exit_color, lw=3 * lw, solid_capstyle="butt")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")


def plot_mesh(ax, mesh, room=None):
    ax.triplot(mesh.points[:, 0], mesh.points[:, 1], mesh.triangles, lw=0.3, color="0.4")
    if room is not None:
        plot_room(ax, room)
    ax.set_aspect("equal")


def plot_route(ax, mesh, phi, directions=None, room=None, every: int = 1):
    """Route potential phi (contours) and desired directions (arrows at vertices)."""
    tc = ax.tricontourf(mesh.points[:, 0], mesh.points[:, 1], mesh.triangles, phi, levels=20,
                        cmap="viridis")
    if directions is not None:
        idx = np.arange(0, mesh.n_points, every)
        ax.quiver(mesh.points[idx, 0], mesh.points[idx, 1], directions[idx, 0],
                  directions[idx, 1], color="w", scale=40, width=0.002)
    if room is not None:
        plot_room(ax, room)
    return tc


def plot_density(ax, mesh, rho, *, vmax=None, room=None, cmap="magma_r"):
    """Cell density [ped/m^2] as a flat-shaded map. A building's surface mesh is drawn as
    its atlas (:mod:`pedmesh.mesh.atlas`): every level and stair flat, side by side, each
    level named."""
    from .mesh.surface import SurfaceMesh

    if isinstance(mesh, SurfaceMesh):
        from .mesh.atlas import build_atlas

        atlas = build_atlas(mesh)
        g = atlas.glued
        tp = ax.tripcolor(g.points[:, 0], g.points[:, 1], g.triangles, facecolors=rho,
                          vmin=0.0, vmax=vmax, cmap=cmap, shading="flat")
        from matplotlib.collections import LineCollection

        walls = g.points[g.edges[g.boundary_edges]]  # (k, 2, 2): the walls and exits
        ax.add_collection(LineCollection(walls, lw=0.4, colors="0.3"))
        for p, off in zip(mesh.pieces, atlas.offset):
            if p.kind == "level":
                top = p.mesh.points.max(axis=0) + off
                mid = 0.5 * (p.mesh.points.min(axis=0) + p.mesh.points.max(axis=0)) + off
                ax.text(mid[0], top[1] + 0.5, p.name, ha="center", va="bottom", fontsize=6)
        ax.set_aspect("equal")
        return tp
    tp = ax.tripcolor(mesh.points[:, 0], mesh.points[:, 1], mesh.triangles, facecolors=rho,
                      vmin=0.0, vmax=vmax, cmap=cmap, shading="flat")
    if room is not None:
        plot_room(ax, room)
    ax.set_aspect("equal")
    return tp


def plot_building_density(ax, surface, rho, *, vmax=None, cmap="magma_r", walls=True):
    """A building's cell density [ped/m^2] on its surface in 3-D (``ax`` a matplotlib 3-D
    axes): every level at its height, the stairs sloped, the walls as lines."""
    from matplotlib import cm, colors
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    norm = colors.Normalize(0.0, vmax if vmax is not None else float(np.max(rho)) or 1.0)
    import matplotlib

    fc = matplotlib.colormaps[cmap](norm(np.asarray(rho, float)))
    ax.add_collection3d(Poly3DCollection(surface.points[surface.triangles], facecolors=fc,
                                         edgecolors="none", linewidths=0))
    if walls:
        seg = surface.points[surface.segments]
        ax.add_collection3d(Line3DCollection(seg, colors="0.25", linewidths=0.4))
    lo, hi = surface.points.min(axis=0), surface.points.max(axis=0)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(hi - lo + 1e-9)
    ax.set_xlabel("x [m]", fontsize=7)
    ax.set_ylabel("y [m]", fontsize=7)
    ax.set_zlabel("z [m]", fontsize=7)
    sm = cm.ScalarMappable(norm=norm, cmap=cmap)
    sm.set_array([])
    return sm


def plot_crowd(ax, room, positions, *, size=2.0):
    plot_room(ax, room)
    if len(positions):
        ax.scatter(positions[:, 0], positions[:, 1], s=size, c="tab:blue", lw=0)


def plot_evacuation(ax, curves: dict, n_total: float):
    """Cumulative number out against time for several runs: {label: (t, n)}."""
    for label, (t, n) in curves.items():
        ax.plot(t, n, label=label)
    ax.axhline(n_total, color="0.7", lw=0.8, ls=":")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("pedestrians out")
    ax.legend(fontsize=8)


def plot_outflow(ax, flows: dict):
    """Total exit outflow [ped/s] against time: {label: (t, flow)}."""
    for label, (t, f) in flows.items():
        ax.plot(t, f, label=label, lw=1)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("outflow f_c [ped/s]")
    ax.legend(fontsize=8)


def plot_fundamental(ax, diagrams: dict, reference=None):
    """Mean local flow per density bin: {label: DensityFlowDiagram}; reference (rho, f)."""
    for label, d in diagrams.items():
        ok = np.isfinite(d.mean_flow)
        ax.plot(d.centers[ok], d.mean_flow[ok], ".", ms=2, label=label)
    if reference is not None:
        ax.plot(*reference, "k-", lw=1, label="f_d = rho U_e(rho)")
    ax.set_xlabel("density [ped/m^2]")
    ax.set_ylabel("flow [ped/(m s)]")
    ax.legend(fontsize=8)
