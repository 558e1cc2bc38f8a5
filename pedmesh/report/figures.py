"""The report's pictures, drawn with matplotlib, each returned as a PNG ``data:`` URI: the
room plan, the evacuation curves, the exit flows, the peak-density and level-of-service
maps, the density snapshots and an ensemble's bands and spread."""

from __future__ import annotations

import base64
import io
import math
from typing import Sequence

import numpy as np

from ..errors import PedmeshError
from ..io.run_folder import SAFETY_VTU
from .load import Ensemble, Frames, Run
from .measures import LOS, los_index, los_scale, moving_mean
from .text import float_or_none, is_num

__all__ = ["VMAX", "plan_figure", "evac_figure", "flow_figure", "maps_figure", "snapshots",
           "bands_figure", "spread_figure"]

#: the colours of Fruin's levels of service A-F on the maps
_LOS_COLORS = ["#1a9850", "#91cf60", "#d9ef8b", "#fee08b", "#fc8d59", "#d73027"]
#: density [ped/m^2] at the top of the colour scale of the density maps
VMAX = 6.0


def _plt():
    from ..plotting import _plt as plt

    return plt()


def _png(fig, dpi: int = 100) -> str:
    """The figure as a PNG data URI, cropped to what is drawn (the figure is closed)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight", pad_inches=0.08)
    _plt().close(fig)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _png_keep(fig, dpi: int = 100) -> str:
    """The figure as a PNG data URI; the figure stays open (the snapshots redraw it)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _draw_room(ax, room, frames: Frames | None, *, labels: bool = True, lw: float = 1.0):
    """Walls, obstacles, exits (named); the mesh outline if the room file is missing."""
    from matplotlib.patches import Polygon as MplPolygon

    if room is None:
        if frames is not None and frames.layout is not None:
            frames.layout.draw(ax, lw=lw, labels=labels)
            ax.autoscale()
        elif frames is not None:
            _draw_mesh_outline(ax, frames)
        ax.set_aspect("equal")
        return
    out = np.asarray(room.outline + (room.outline[0],))
    ax.plot(out[:, 0], out[:, 1], "k-", lw=lw)
    for o in room.obstacles:
        ax.add_patch(MplPolygon(np.asarray(o.polygon), closed=True, fc="0.55", ec="k", lw=lw,
                                zorder=3))
    for k, e in enumerate(room.exits):
        pl = np.asarray(room.exit_polyline(k))
        ax.plot(pl[:, 0], pl[:, 1], "-", color="#00a651", lw=4 * lw, solid_capstyle="butt",
                zorder=4)
        if labels:
            mid = pl[len(pl) // 2] if len(pl) > 2 else pl.mean(axis=0)
            ax.annotate(e.name, mid, xytext=(4, 4), textcoords="offset points",
                        color="#006b34", fontsize=8, fontweight="bold", zorder=5)
    ax.set_aspect("equal")


def _draw_mesh_outline(ax, frames: Frames) -> None:
    tri = frames.triangles
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    b = uniq[count == 1]
    from matplotlib.collections import LineCollection

    ax.add_collection(LineCollection(frames.points[b], colors="k", linewidths=1.0))
    ax.autoscale()


def _aspect(room, frames: Frames | None) -> float:
    """Height / width of the room's bounding box."""
    if room is not None:
        x0, y0, x1, y1 = room.bounds
    elif frames is not None:
        (x0, y0), (x1, y1) = frames.points.min(axis=0), frames.points.max(axis=0)
    else:
        return 0.6
    return float(np.clip((y1 - y0) / max(x1 - x0, 1e-9), 0.15, 3.0))


def _map_size(aspect: float, rows: int = 1, cols: int = 1, width: float = 8.0, *,
              colorbar: bool = True, extra: float = 0.5) -> tuple[float, float]:
    """A figure size [in] whose panels of the room (``aspect`` = height / width) leave
    little blank: room for the colour bar, the axis labels and the titles."""
    panel_w = (width - (1.3 if colorbar else 0.2)) / cols - 0.75
    h = rows * (panel_w * aspect + 0.85) + extra
    if h > 10.0:  # a tall room: narrower panels
        return _map_size(aspect, rows, cols, width * 10.0 / h, colorbar=colorbar,
                         extra=extra)
    return (width, max(h, 2.2))


def _marker_size(room, frames: Frames | None, panel_width_in: float) -> float:
    """Scatter marker size [pt^2] of a body of about 0.45 m across on the plot."""
    if room is not None:
        x0, _, x1, _ = room.bounds
    elif frames is not None:
        x0, x1 = frames.points[:, 0].min(), frames.points[:, 0].max()
    else:
        return 4.0
    ppm = panel_width_in * 72.0 / max(x1 - x0, 1e-9)
    return float(np.clip((0.45 * ppm) ** 2, 0.5, 40.0))


def plan_figure(run: Run) -> str:
    from matplotlib.patches import Patch, Polygon as MplPolygon
    from matplotlib.lines import Line2D

    plt = _plt()
    room, frames = run.room, run.frames
    fig, ax = plt.subplots(figsize=_map_size(_aspect(room, frames), colorbar=False,
                                             extra=0.9), layout="constrained")
    handles = [Line2D([], [], color="k", lw=1, label="wall"),
               Line2D([], [], color="#00a651", lw=4, label="exit")]
    if room is not None:
        if room.obstacles:
            handles.append(Patch(fc="0.55", ec="k", label="obstacle"))
        walk = room.walkable
        for s in room.start_areas:
            ax.add_patch(MplPolygon(np.asarray(s.polygon), closed=True, fc="#4c72b0",
                                    alpha=0.25, ec="#4c72b0", lw=1))
            try:
                n = len(s.positions(walk))
            except Exception:
                n = s.count
            what = "arrive" if s.arrivals is not None else "at the start"
            c = np.asarray(s.polygon).mean(axis=0)
            ax.text(c[0], c[1], f"{s.name}\n{n} people {what}", ha="center", va="center",
                    fontsize=8, color="#1f3b73")
        if room.start_areas:
            handles.append(Patch(fc="#4c72b0", alpha=0.25, ec="#4c72b0", label="start area"))
        for a in room.measurement_areas:
            ax.add_patch(MplPolygon(np.asarray(a.polygon), closed=True, fill=False,
                                    ec="#8e44ad", ls="--", lw=1.2))
            c = np.asarray(a.polygon).mean(axis=0)
            ax.text(c[0], c[1], a.name, ha="center", va="center", fontsize=7, color="#8e44ad")
        for m in room.measurement_lines:
            pl = np.asarray(m.polyline)
            ax.plot(pl[:, 0], pl[:, 1], ls=":", color="#8e44ad", lw=1.5)
        if room.measurement_areas or room.measurement_lines:
            handles.append(Line2D([], [], color="#8e44ad", ls="--", label="measurement"))
    _draw_room(ax, room, frames)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=5,
              fontsize=8, frameon=False)
    if room is not None:
        title = f"room '{room.name}'"
    elif frames is not None and frames.layout is not None:
        title = (f"building '{run.s.get('room', '?')}': one panel per level; stairs dashed, "
                 "with the level each leads to")
    else:
        title = "mesh outline"
    ax.set_title(title, fontsize=10)
    return _png(fig, 100)


_COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2",
           "#17becf", "#7f7f7f", "#bcbd22"]


def evac_figure(runs: Sequence[Run]) -> str:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 4.2), layout="constrained")
    single = len(runs) == 1
    n_max = 0.0
    for i, r in enumerate(runs):
        t, n = r.evacuation
        c = _COLORS[i % len(_COLORS)]
        if len(t):
            ax.plot(t, n, color=c, lw=1.6, label=r.label if not single else "people out")
        n0 = r.s.get("n_initial") or (n[-1] if len(n) else 0)
        n_max = max(n_max, float(n0 or 0))
        for key, frac, mk in (("t_evac_50", 0.5, "o"), ("t_evac_90", 0.9, "s"),
                              ("t_evac_100", 1.0, "^")):
            tv = r.s.get(key)
            if not is_num(tv):
                continue
            name = "T" + key.rsplit("_", 1)[1]
            if single:
                ax.axvline(tv, color="0.45", ls=":", lw=1)
                ax.annotate(f"{name} = {tv:.1f} s", (tv, 0.02),
                            xycoords=("data", "axes fraction"),
                            xytext=(-3, 0), textcoords="offset points", rotation=90,
                            ha="right", va="bottom", fontsize=9)
            ax.plot([tv], [frac * float(n0)], mk, color=c, ms=6, mec="k", mew=0.5)
    if n_max:
        ax.axhline(n_max, color="0.75", lw=0.8, ls="--")
    ax.set_xlabel("time t [s]")
    ax.set_ylabel("people out [persons]")
    ax.set_ylim(0, max(n_max * 1.05, 1))
    ax.set_xlim(left=0)
    ax.grid(alpha=0.3)
    if not single:
        from matplotlib.lines import Line2D

        h, _ = ax.get_legend_handles_labels()
        h += [Line2D([], [], ls="", marker=m, color="0.3", label=lab)
              for m, lab in (("o", "T50"), ("s", "T90"), ("^", "T100"))]
        ax.legend(handles=h, fontsize=8, loc="lower right")
    ax.set_title("evacuation: people out over time" + (" (T50, T90, T100 marked)"
                                                       if not single else ""), fontsize=10)
    return _png(fig, 100)


def flow_figure(runs: Sequence[Run]) -> str | None:
    plt = _plt()
    exits: list[str] = []
    for r in runs:
        for n in r.outflow[2]:
            if n not in exits:
                exits.append(n)
    if not exits:
        return None
    single = len(runs) == 1
    panels = [None] if single or len(exits) > 6 else exits
    fig, axes = plt.subplots(len(panels), 1, figsize=(8, 2.6 + 1.8 * (len(panels) - 1)),
                             layout="constrained", squeeze=False, sharex=True)
    for pi, which in enumerate(panels):
        ax = axes[pi, 0]
        for i, r in enumerate(runs):
            t, f, names = r.outflow
            if len(t) < 2:
                continue
            if single:
                for k, n in enumerate(names):
                    ax.plot(t, moving_mean(t, f[:, k]), lw=1.4, label=f"exit '{n}'",
                            color=_COLORS[k % len(_COLORS)])
            elif which is None:
                ax.plot(t, moving_mean(t, f.sum(axis=1)), lw=1.4, label=r.label,
                        color=_COLORS[i % len(_COLORS)])
            elif which in names:
                ax.plot(t, moving_mean(t, f[:, names.index(which)]), lw=1.4, label=r.label,
                        color=_COLORS[i % len(_COLORS)])
        ax.set_ylabel("flow [ped/s]")
        ax.grid(alpha=0.3)
        ax.set_ylim(bottom=0)
        ax.set_xlim(left=0)
        title = ("all exits" if which is None and not single else
                 f"exit '{which}'" if which is not None else "")
        if title:
            ax.set_title(title, fontsize=9)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8, loc="upper right")
    axes[-1, 0].set_xlabel("time t [s]")
    fig.suptitle("flow through the exits (mean over 2 s)", fontsize=10)
    return _png(fig, 100)


def _map_panels(plt, have: Sequence[Run]):
    """A figure with a panel of the room per run of ``have`` (1, 2 or 3 columns; spare
    panels blank): (figure, axes array, figure size [in], [(run, its axes)])."""
    n = len(have)
    cols = 1 if n == 1 else 2 if n <= 4 else 3
    rows = math.ceil(n / cols)
    size = _map_size(_aspect(have[0].room, have[0].frames), rows, cols,
                     8.0 if cols == 1 else 11.0)
    fig, axes = plt.subplots(rows, cols, figsize=size, layout="constrained", squeeze=False)
    for ax in axes.ravel()[n:]:
        ax.set_axis_off()
    return fig, axes, size, list(zip(have, axes.ravel()))


def _safety_maps(r: "Run", fr) -> tuple[np.ndarray, np.ndarray, bool]:
    """Each cell's peak density [ped/m^2] and worst level of service (0-5) of a run: the
    crowd-safety measures' own maps (``safety.vtu``, the density on 1 m^2) where the run
    wrote them on the frames' mesh, else the peaks of the saved frames; and which."""
    path = r.path / SAFETY_VTU
    if path.is_file():
        try:
            from ..io.vtk import read_vtu

            _, tri, _, cells = read_vtu(path, cell_arrays=("peak_density", "worst_los"))
            if len(tri) == len(fr.triangles):
                return (np.asarray(cells["peak_density"], float),
                        np.asarray(cells["worst_los"]).astype(int), True)
        except Exception:  # (a damaged file: fall back to the frames, and say so)
            r.notes.append(f"{path.name} could not be read; the maps use the saved frames")
    peak, _ = fr.peak
    return peak, los_index(peak, los_scale(r.safety)), False


def maps_figure(runs: Sequence[Run], what: str) -> str | None:
    """Peak density (``what='peak'``) or worst level of service (``'los'``) per cell,
    one panel per run."""
    from matplotlib.colors import BoundaryNorm, ListedColormap

    plt = _plt()
    have = [r for r in runs if r.frames is not None]
    if not have:
        return None
    fig, axes, _, panels = _map_panels(plt, have)
    mappable = None
    for r, ax in panels:
        fr = r.frames
        peak, worst, measured = _safety_maps(r, fr)
        if what == "peak":
            mappable = ax.tripcolor(fr.points[:, 0], fr.points[:, 1], fr.triangles,
                                    facecolors=peak, vmin=0, vmax=VMAX, cmap="magma_r",
                                    shading="flat")
        else:
            idx = worst
            cmap = ListedColormap(_LOS_COLORS)
            mappable = ax.tripcolor(fr.points[:, 0], fr.points[:, 1], fr.triangles,
                                    facecolors=idx.astype(float), cmap=cmap,
                                    norm=BoundaryNorm(np.arange(-0.5, 6.5), 6), shading="flat")
        _draw_room(ax, r.room, fr, labels=len(have) == 1)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        if len(have) > 1:
            ax.set_title(r.label, fontsize=9)
    if what == "peak":
        cb = fig.colorbar(mappable, ax=axes, shrink=0.85, extend="max")
        cb.set_label("peak density [ped/m²]" + (" on 1 m²" if measured else ""))
        fig.suptitle("largest density of each mesh cell over the run"
                     + (" (safety.vtu: on 1 m²)" if measured else " (the saved frames)"),
                     fontsize=10)
    else:
        cb = fig.colorbar(mappable, ax=axes, shrink=0.85, ticks=range(6))
        cb.ax.set_yticklabels(list(LOS))
        scale = los_scale(have[0].safety)
        cb.set_label(f"worst level of service (Fruin, {scale})")
        fig.suptitle("worst level of service of each mesh cell over the run", fontsize=10)
    return _png(fig, 100)


def _snapshot_times(runs: Sequence[Run], n: int) -> list[float]:
    """Up to ``n`` times [s] of saved frames, evenly spread from the start to the last
    frame of the longest run."""
    fr = [r.frames for r in runs if r.frames is not None]
    if not fr:
        return []
    longest = max(fr, key=lambda f: f.times[-1])
    times = longest.times
    if len(times) <= n:
        return [float(t) for t in times]
    pick = np.unique(np.round(np.linspace(0, len(times) - 1, n)).astype(int))
    return [float(times[k]) for k in pick]


def snapshots(runs: Sequence[Run], n: int) -> tuple[list[str], list[str]]:
    """(images, labels) of the density at the snapshot times, the runs side by side."""
    plt = _plt()
    have = [r for r in runs if r.frames is not None]
    times = _snapshot_times(have, n)
    if not times:
        return [], []
    fig, axes, size, panels = _map_panels(plt, have)
    dot = _marker_size(have[0].room, have[0].frames,
                       (size[0] - 1.3) / axes.shape[1] - 0.75)
    arts = []
    for r, ax in panels:
        fr = r.frames
        tp = ax.tripcolor(fr.points[:, 0], fr.points[:, 1], fr.triangles,
                          facecolors=np.zeros(len(fr.triangles)), vmin=0, vmax=VMAX,
                          cmap="magma_r", shading="flat")
        _draw_room(ax, r.room, fr, labels=len(have) == 1)
        sc = ax.scatter(np.zeros(0), np.zeros(0), s=dot, c="#1f77b4", lw=0, zorder=6) \
            if r.ped_frames else None
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        arts.append((r, ax, tp, sc))
    cb = fig.colorbar(arts[0][2], ax=axes, shrink=0.85, extend="max")
    cb.set_label("density [ped/m²]")
    for _, ax, _, _ in arts:
        ax.set_title("t = 0000 s", fontsize=9)
    fig.canvas.draw()  # lay the figure out once; the frames only change colours and titles
    fig.set_layout_engine("none")
    images, labels = [], []
    for t in times:
        for r, ax, tp, sc in arts:
            fr = r.frames
            k = int(np.argmin(np.abs(fr.times - t)))
            ended = t > fr.times[-1] + 1e-6
            rho = None if ended else fr.density(k)
            tp.set_array(np.zeros(len(fr.triangles)) if rho is None else rho)
            name = f"{r.label}: " if len(have) > 1 else ""
            if ended:
                ax.set_title(f"{name}run ended at {fr.times[-1]:.0f} s", fontsize=9)
            else:
                ax.set_title(f"{name}t = {fr.times[k]:.0f} s", fontsize=9)
            if sc is not None:
                pos = None if ended else r.positions_at(float(fr.times[k]))
                sc.set_offsets(np.zeros((0, 2)) if pos is None else pos)
        images.append(_png_keep(fig, 100))
        labels.append(f"t = {t:.0f} s")
    plt.close(fig)
    return images, labels


def bands_figure(ens: Ensemble) -> str | None:
    """The median evacuation curve of each sweep point and its 5-95 % band over the
    finished members (None if no member has a curve)."""
    from ..ensembles.stats import evacuation_band
    from ..run.results import RunResult

    bands = []  # (sweep point's index, entry, members, (t, lo, median, hi))
    for i, pt in enumerate(ens.points):
        curves = []
        for r in ens.finished(str(pt.get("point", 0))):
            try:
                curves.append(RunResult.load(ens.member_dir(r["member"])).evacuation)
            except (PedmeshError, OSError, ValueError, IndexError):
                continue
        curves = [c for c in curves if len(c[0])]
        if curves:
            bands.append((i, pt, len(curves), evacuation_band(curves)))
    if not bands:
        return None
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 4.2), layout="constrained")
    for i, pt, n, (grid, lo, med, hi) in bands:
        c = _COLORS[i % len(_COLORS)]
        ax.plot(grid, med, color=c, lw=1.6, label=f"{ens.point_label(pt)}: median of {n} runs")
        ax.fill_between(grid, lo, hi, color=c, alpha=0.25, lw=0, label="5-95 % band")
    ax.set_xlabel("time t [s]")
    ax.set_ylabel("people out [persons]")
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("evacuation over the members: median and 5-95 % band", fontsize=10)
    return _png(fig, 100)


def spread_figure(ens: Ensemble) -> str | None:
    """T50/T90/T100 of every finished member, per sweep point."""
    plt = _plt()
    pts = ens.points
    fig, ax = plt.subplots(figsize=(8, 1.2 + 0.9 * max(len(pts), 1)), layout="constrained")
    drawn = False
    rng = np.random.default_rng(0)
    for i, pt in enumerate(pts):
        done = ens.finished(str(pt.get("point", 0)))
        for j, (key, c) in enumerate((("t_evac_50", "#1f77b4"), ("t_evac_90", "#d62728"),
                                      ("t_evac_100", "#2ca02c"))):
            v = np.array([x for x in (float_or_none(r.get(key)) for r in done)
                          if x is not None])
            if not len(v):
                continue
            y = i + (j - 1) * 0.22 + rng.uniform(-0.06, 0.06, len(v))
            ax.plot(v, y, "o", ms=3.5, color=c, alpha=0.7,
                    label=f"T{key.rsplit('_', 1)[1]}" if i == 0 else None)
            drawn = True
    if not drawn:
        plt.close(fig)
        return None
    ax.set_yticks(range(len(pts)))
    ax.set_yticklabels([ens.point_label(p) for p in pts], fontsize=8)
    ax.set_xlabel("time [s]")
    ax.grid(alpha=0.3, axis="x")
    ax.legend(fontsize=8, loc="best")
    ax.set_title("evacuation times of every member", fontsize=10)
    return _png(fig, 100)
