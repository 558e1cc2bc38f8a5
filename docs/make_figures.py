"""Draw the pictures of the README and the docs into docs/images/.

    python docs/make_figures.py

The mesh and route pictures are computed here (seconds); the density snapshot and the
evacuation comparison are read from the runs of ``examples/reproduce_paper.py`` in
``examples/results/example2/`` (run that first).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pedmesh.mesh import triangulate

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "images"


def main() -> None:
    from pedmesh import load_room
    from pedmesh.analysis import vertex_to_cell
    from pedmesh.eikonal import DirectionField, solve_eikonal
    from pedmesh.plotting import _plt, plot_density, plot_evacuation, plot_mesh, plot_route
    from pedmesh.run.results import RunResult

    plt = _plt()
    OUT.mkdir(parents=True, exist_ok=True)
    hall = load_room(ROOT / "geometries" / "pillar_hall.json")
    mesh = triangulate(hall, max_area=1.0)
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    plot_mesh(ax, mesh, hall)
    ax.set_title(f"pillar_hall.json: {mesh.n_triangles} triangles (max_area 1 m^2)", fontsize=9)
    fig.tight_layout()
    fig.savefig(OUT / "mesh.png", dpi=100)
    plt.close(fig)

    fine = triangulate(hall, max_area=0.1)
    phi = solve_eikonal(fine)
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    tc = plot_route(ax, fine, phi, room=hall)
    g = np.stack(np.meshgrid(np.arange(1.0, 40, 1.5), np.arange(1.0, 30, 1.5)), -1).reshape(-1, 2)
    d = DirectionField(fine, phi).at(g)
    ok = np.hypot(d[:, 0], d[:, 1]) > 0
    ax.quiver(g[ok, 0], g[ok, 1], d[ok, 0], d[ok, 1], color="w", scale=45, width=0.003)
    fig.colorbar(tc, ax=ax, label="phi: walking time to the nearest exit [s] (empty room)")
    ax.set_title("route potential and desired directions", fontsize=9)
    fig.tight_layout()
    fig.savefig(OUT / "route.png", dpi=100)
    plt.close(fig)

    _office(plt)

    res = ROOT / "examples" / "results" / "example2"
    if not (res / "sfm" / "summary.json").exists():
        print("no Example 2 runs in examples/results: run examples/reproduce_paper.py first")
        return
    room = load_room(ROOT / "geometries" / "example2.json")
    m2 = triangulate(room)
    def finished(path):
        return (path / "summary.json").exists() and RunResult.load(path).finished

    labels = [m for m in ("sfm", "eos", "mac1") if finished(res / m)]
    fig, axes = plt.subplots(1, len(labels), figsize=(4.2 * len(labels), 2.6), squeeze=False)
    tp = None
    for ax, lab in zip(axes[0], labels):
        t, rho, _ = RunResult.load(res / lab).density_at(50.0, m2)
        tp = plot_density(ax, m2, rho, vmax=6.0, room=room)
        ax.set_title(f"{lab}, t = {t:.0f} s", fontsize=9)
        ax.tick_params(labelsize=7)
    fig.colorbar(tp, ax=axes, shrink=0.85, label="density [ped/m^2]")
    fig.savefig(OUT / "density.png", dpi=100, bbox_inches="tight")
    plt.close(fig)

    runs = {p.name: RunResult.load(p) for p in sorted(res.iterdir())
            if finished(p) and not p.name.startswith("eos_exit")}
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    plot_evacuation(ax, {k: r.evacuation for k, r in runs.items()}, 2400)
    ax.set_title("Example 2: pedestrians out, every model", fontsize=9)
    fig.tight_layout()
    fig.savefig(OUT / "evacuation.png", dpi=100)
    plt.close(fig)
    print(f"wrote the pictures into {OUT}")


def _office(plt) -> None:
    """The shipped building under eos (computed here, 10 s): the density on its surface in
    3-D at t = 30 s."""
    import tempfile

    from pedmesh import load_room
    from pedmesh.mesh import triangulate_building
    from pedmesh.plotting import plot_building_density
    from pedmesh.run import run_model
    from pedmesh.run.results import RunResult

    b = load_room(ROOT / "geometries" / "office.json")
    s = triangulate_building(b)
    with tempfile.TemporaryDirectory() as d:
        run_model(b, s, "eos", out_dir=Path(d) / "eos", quiet=True, t_end=31.0)
        t, rho, _ = RunResult.load(Path(d) / "eos").density_at(30.0, s)
    fig = plt.figure(figsize=(6.4, 4.4))
    ax = fig.add_subplot(projection="3d")
    sm = plot_building_density(ax, s, rho, vmax=3.0)
    ax.view_init(elev=22, azim=-62)
    ax.tick_params(labelsize=6)
    fig.colorbar(sm, ax=ax, shrink=0.6, pad=0.12, label="density [ped/m^2]")
    ax.set_title(f"office.json under eos, t = {t:.0f} s: five storeys, two stairwells",
                 fontsize=9)
    fig.savefig(OUT / "office.png", dpi=110, bbox_inches="tight")
    plt.close(fig)


if __name__ == "__main__":
    main()
