"""An animation of a run: the density field (continuum models) or the crowd (particle
models) over the room, with a clock, as MP4 or GIF (``pedmesh animate``). A building is
drawn as plans, one panel per level, each stair where it is
(:mod:`pedmesh.run.layout`).

The frames are the run's own output frames (density and pedestrians, one per output
interval, read by :class:`~pedmesh.run.results.RunResult`). MP4 is written with the ffmpeg
binary of the ``imageio-ffmpeg`` wheel through matplotlib's writer, GIF with Pillow:
nothing needs a system ffmpeg.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import PedmeshError

__all__ = ["animate_run", "FORMATS"]

#: the file types :func:`animate_run` writes
FORMATS = (".mp4", ".gif")
#: [ped/m^2] the top of the colour scale
VMAX = 6.0


class _Frames:
    """A run's output frames (density, and for particle models the pedestrians)."""

    def __init__(self, run_dir: Path) -> None:
        from .io.run_folder import DENSITY_PVD
        from .io.vtk import read_vtu
        from .run.results import RunResult

        self.dir = run_dir
        self.result = RunResult.load(run_dir)
        pvd = self.result.file(DENSITY_PVD)
        if not pvd.is_file():
            raise PedmeshError(f"{run_dir}: no {DENSITY_PVD} (not a run folder, or a run "
                               "that wrote no frames)")
        self.density = self.result.density_frames
        if not self.density:
            raise PedmeshError(f"{pvd}: no frames")
        self.pedestrians = dict(self.result.pedestrian_frames)
        self.layout = None  # a building's plans (one panel per level), else the plan
        self.note = ""
        from .io.vtk import check_frames_whole

        # (every frame whole, not only those shown)
        check_frames_whole([f for _, f in self.density] + list(self.pedestrians.values()))
        first = read_vtu(self.density[0][1])
        self._read = {0: first}  # (the first frame, read once: field(0) takes it)
        pts, tri, _, _ = first
        self._mesh = (len(pts), np.asarray(tri))
        if np.ptp(np.asarray(pts)[:, 2]) > 0:  # a building with floors above each other
            from .run.layout import building_layout

            self.layout, self.note = building_layout(self.result.summary, run_dir, len(tri))

    def field(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(points (n, 2), triangles (m, 3), cell density (m,) [ped/m^2]) of frame k."""
        from .io.vtk import check_same_mesh, frame_density, read_vtu

        got = self._read.pop(k, None)
        path = self.density[k][1]
        pts, tri, pd, cd = got if got is not None else read_vtu(path)
        check_same_mesh(path, pts, tri, *self._mesh)
        rho = frame_density(path, pd, cd, tri)
        if self.layout is not None:
            return self.layout.points, self.layout.triangles, rho
        return np.asarray(pts)[:, :2], np.asarray(tri), rho

    def crowd(self, t: float) -> tuple[np.ndarray, np.ndarray] | None:
        """(positions (k, 2) [m], speeds (k,) [m/s]) of the pedestrians frame at ``t``."""
        from .io.vtk import read_vtp

        path = self.pedestrians.get(t)
        if path is None:
            return None
        pts, data = read_vtp(path)
        speed = np.asarray(data.get("speed", np.zeros(len(pts))), float)
        if self.layout is not None and "piece" in data:
            return self.layout.crowd(pts, data["piece"]), speed
        return np.asarray(pts)[:, :2], speed


def animate_run(run_dir: str | Path, out: str | Path, *, fps: float = 10.0,
                max_frames: int = 600, dpi: int = 100) -> Path:
    """Write the animation of the run in ``run_dir`` to ``out`` (.mp4 or .gif): one picture
    per output frame (at most ``max_frames``, evenly picked), ``fps`` pictures per second of
    video. Returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import animation

    out = Path(out)
    suffix = out.suffix.lower()
    if suffix not in FORMATS:
        raise PedmeshError(f"{out}: the animation is written as {' or '.join(FORMATS)}; "
                           "use one of those suffixes")
    import numbers

    if isinstance(fps, bool) or not isinstance(fps, numbers.Real) or not (
            np.isfinite(fps) and 0.1 <= fps <= 120):
        raise PedmeshError(f"--fps must be between 0.1 and 120 frames per second, got {fps!r}")
    if not (isinstance(max_frames, int) and max_frames >= 1):
        raise PedmeshError(f"--max-frames must be a positive whole number, got {max_frames!r}")
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise PedmeshError(f"{run_dir}: no such run folder")
    from .run.output import check_writable, temporary_beside, write_error

    check_writable(out)  # (before the minutes of drawing)
    frames = _Frames(run_dir)
    if frames.note:
        import sys

        print(f"note: {frames.note}", file=sys.stderr)
    s = frames.result.summary
    pick = np.unique(np.round(np.linspace(0, len(frames.density) - 1,
                                          min(max_frames, len(frames.density)))).astype(int))
    pts, tri, rho = frames.field(int(pick[0]))
    x0, y0 = pts.min(axis=0)
    x1, y1 = pts.max(axis=0)
    if frames.layout is not None and frames.layout.panels:  # (the levels' panels, names)
        box = np.asarray(frames.layout.panels, float)
        x0, y0 = box[:, :2].min(axis=0) + 0.5
        x1, y1 = box[:, 2:].max(axis=0) - 0.5
    aspect = (y1 - y0) / max(x1 - x0, 1e-9)
    width = 8.0
    fig, ax = plt.subplots(figsize=(width, max(2.5, min(8.0, width * aspect + 1.2))),
                           layout="constrained")
    mesh = ax.tripcolor(pts[:, 0], pts[:, 1], tri, facecolors=rho, vmin=0.0, vmax=VMAX,
                        cmap="magma_r", shading="flat")
    cb = fig.colorbar(mesh, ax=ax, shrink=0.85, extend="max")
    cb.set_label("density [ped/m²]")
    if frames.layout is not None:
        frames.layout.draw(ax)
    else:
        _outline(ax, pts, tri)
    dots = ax.scatter([], [], s=6, c="#1f77b4", edgecolors="none")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_xlim(x0 - 0.5, x1 + 0.5)
    ax.set_ylim(y0 - 0.5, y1 + 0.5)
    model = s.get("model", "?")
    clock = ax.set_title("")
    n0 = float(s.get("n_initial") or 0)
    t_ev, n_ev = frames.result.evacuation

    failed: list[PedmeshError] = []  # (matplotlib's writers hide an error in a frame)

    def draw(k: int):
        try:
            return drawn(k)
        except PedmeshError as exc:
            failed.append(exc)
            raise

    def drawn(k: int):
        t = frames.density[k][0]
        _, _, r = frames.field(k)
        mesh.set_array(r)
        crowd = frames.crowd(t)
        if crowd is not None:
            dots.set_offsets(crowd[0] if len(crowd[0]) else np.zeros((0, 2)))
        out_now = float(np.interp(t, t_ev, n_ev)) if len(t_ev) else 0.0
        clock.set_text(f"{model} on '{s.get('room', '?')}'   t = {t:6.1f} s   "
                       f"out {out_now:.0f} of {n0:.0f}")
        return mesh, dots, clock

    anim = animation.FuncAnimation(fig, draw, frames=[int(k) for k in pick], blit=False)
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        tmp = temporary_beside(out)  # (a name of its own: never a file of the user's)
    except OSError as exc:
        plt.close(fig)
        raise write_error(out, exc) from None
    try:
        if suffix == ".mp4":
            import imageio_ffmpeg

            matplotlib.rcParams["animation.ffmpeg_path"] = imageio_ffmpeg.get_ffmpeg_exe()
            writer = animation.FFMpegWriter(fps=fps, codec="libx264",
                                            extra_args=["-pix_fmt", "yuv420p"])
        else:
            writer = animation.PillowWriter(fps=fps)
        anim.save(tmp, writer=writer, dpi=dpi)
        tmp.replace(out)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if failed:  # a frame that could not be read, not the video
            raise failed[0] from None
        if isinstance(exc, OSError) and not isinstance(exc, PedmeshError):
            raise write_error(out, exc) from None
        raise
    finally:
        plt.close(fig)
    return out


def _outline(ax, pts: np.ndarray, tri: np.ndarray) -> None:
    """The mesh's boundary edges (walls, obstacles, exits) as black lines."""
    from matplotlib.collections import LineCollection

    e = np.sort(tri[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1)
    edges, counts = np.unique(e, axis=0, return_counts=True)
    b = edges[counts == 1]
    ax.add_collection(LineCollection(pts[b], colors="k", linewidths=1.2))
