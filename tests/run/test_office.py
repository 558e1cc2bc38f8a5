"""The shipped building (geometries/office.json) through `pedmesh compare`: the social force
model and eos evacuate it, eos's T90 within 10 % of the social force model's, the density
frames in 3-D, the trajectories naming the level and carrying z, one level for PedPy."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from pedmesh.cli import main
from pedmesh.io import load_room
from pedmesh.mesh.building import triangulate_building

ROOT = Path(__file__).resolve().parents[2]
OFFICE = ROOT / "geometries" / "office.json"


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    out = tmp_path_factory.mktemp("office")
    assert main(["compare", str(OFFICE), "--models", "sfm,eos", "--out", str(out), "-q"]) == 0
    return out


def test_both_models_get_everyone_out(compared):
    rows = {r["label"]: r for r in csv.DictReader(open(compared / "comparison.csv"))}
    for r in (rows["sfm"], rows["eos"]):
        assert float(r["t_evac_100"]) > 0  # everyone out
    assert (compared / "density.png").stat().st_size > 10_000


@pytest.mark.xfail(strict=True, reason=(
    "a known miss (issue 45): since the social force model's density cone reads a stair's "
    "crowd with unit directions (it read it at the stair's speed factor squared), its T90 "
    "on the office is 118.7 s and eos's 103.8 s (-12.6 %; -5.7 % before, the three-storey "
    "building now within 0.2 %): the west stairs carry 48 of each floor's 60 people in the "
    "social force model, fewer in eos, and pass 0.74 /(m s) against eos's 0.82"))
def test_eos_answers_like_the_social_force_model(compared):
    rows = {r["label"]: r for r in csv.DictReader(open(compared / "comparison.csv"))}
    sfm, eos = rows["sfm"], rows["eos"]
    assert abs(float(eos["t_evac_90"]) / float(sfm["t_evac_90"]) - 1.0) < 0.10


def test_the_density_frames_are_in_3d(compared):
    from pedmesh.io.vtk import read_vtu

    s = triangulate_building(load_room(OFFICE))
    frames = sorted((compared / "eos" / "density").glob("*.vtu"))
    pts, tri, point, cell = read_vtu(frames[len(frames) // 3])
    assert np.array_equal(tri, s.triangles) and np.allclose(pts, s.points)
    assert pts[:, 2].max() == pytest.approx(14.0)  # the fourth floor
    # the velocity is 3-D and along the surface: normal to each triangle's normal
    v = cell["velocity"]
    assert v.shape == (s.n_triangles, 3) and np.abs(v).max() > 0.1
    assert np.abs(np.sum(v * s.normals, axis=1)).max() < 1e-9
    assert point["phi"].shape == (s.n_points,)
    import json

    summary = json.loads((compared / "eos" / "summary.json").read_text())
    assert summary["mass_error_max"] < 1e-12


def test_the_trajectories_name_the_level(compared, tmp_path):
    pedpy = pytest.importorskip("pedpy")
    from pedmesh.analysis import level_trajectories

    b = load_room(OFFICE)
    d = compared / "sfm"
    rows = [ln.split() for ln in (d / "trajectories.txt").read_text().splitlines()
            if not ln.startswith("#")]
    places = {r[5] for r in rows}
    assert {"ground", "fourth", "west-3-4", "east-0-1"} <= places
    z = np.array([float(r[4]) for r in rows])
    assert z.min() == 0.0 and z.max() == pytest.approx(14.0)
    # one level's rows for PedPy, with that level's walkable area
    out = level_trajectories(d / "trajectories.sqlite", "second", tmp_path / "second.sqlite",
                             walkable_wkt=b.level("second").room.walkable.wkt)
    traj = pedpy.load_trajectory_from_jupedsim_sqlite(trajectory_file=out)
    assert len(traj.data) == sum(r[5] == "second" for r in rows)
    walk = pedpy.load_walkable_area_from_jupedsim_sqlite(trajectory_file=out)
    assert walk.polygon.area == pytest.approx(b.level("second").room.walkable.area)
    # the pedestrians' frames are in 3-D too
    from pedmesh.io.vtk import read_vtp

    frames = sorted((d / "pedestrians").glob("*.vtp"))
    pts, data = read_vtp(frames[len(frames) // 4])
    assert pts.shape[1] == 3 and pts[:, 2].max() > 3.0 and "piece" in data


def test_report_and_animation_lay_the_floors_side_by_side(compared, tmp_path):
    """The report and the animation draw a building as plans (one panel per level, stacked
    floors apart, each stair in its bottom level's panel where it is), every pedestrian on
    the piece their frame names."""
    import json

    from pedmesh.io.vtk import read_pvd_index, read_vtp
    from pedmesh.run.layout import building_layout

    run = compared / "sfm"
    summary = json.loads((run / "summary.json").read_text())
    s = triangulate_building(load_room(OFFICE))
    layout, note = building_layout(summary, run, s.n_triangles)
    assert note == "" and layout is not None
    assert np.array_equal(layout.triangles, layout.atlas.open.triangles)
    # stacked floors apart: no two levels' boxes overlap in the layout
    levels = [p for p in s.pieces if p.kind == "level"]
    boxes = [layout.points[np.unique(layout.triangles[p.triangles])] for p in levels]
    lo = np.array([b.min(axis=0) for b in boxes])
    hi = np.array([b.max(axis=0) for b in boxes])
    k = len(boxes)
    overlap = ((lo[:, None] < hi[None] - 1e-9) & (lo[None] < hi[:, None] - 1e-9)).all(axis=2)
    assert not overlap[~np.eye(k, dtype=bool)].any()
    # in plan: each level's cells at their plan position shifted to its panel
    plan = np.asarray(s.points)[:, :2]
    for p in levels:
        v = np.unique(layout.triangles[p.triangles])
        shift = layout.points[v] - plan[layout.atlas.to_surface[v]]
        assert np.allclose(shift, layout.panel_shift[p.name])
    # every pedestrian of a frame mid-run lies in a triangle of their own piece
    frames = read_pvd_index(run / "pedestrians.pvd")
    pts, data = read_vtp(frames[len(frames) // 4][1])
    piece = np.asarray(data["piece"], np.int64)
    xy = layout.crowd(pts, piece)
    assert len(xy) > 50
    for q, k in zip(xy, piece):
        corners = layout.points[layout.triangles[s.pieces[k].triangles]]  # (t, 3, 2)
        a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
        d = (b[:, 1] - c[:, 1]) * (a[:, 0] - c[:, 0]) + (c[:, 0] - b[:, 0]) * (a[:, 1] - c[:, 1])
        w1 = ((b[:, 1] - c[:, 1]) * (q[0] - c[:, 0]) + (c[:, 0] - b[:, 0]) * (q[1] - c[:, 1])) / d
        w2 = ((c[:, 1] - a[:, 1]) * (q[0] - c[:, 0]) + (a[:, 0] - c[:, 0]) * (q[1] - c[:, 1])) / d
        inside = (w1 >= -1e-6) & (w2 >= -1e-6) & (1 - w1 - w2 >= -1e-6)
        assert inside.any()
    # the report says so, and the animation is written
    out = tmp_path / "office.html"
    assert main(["report", str(run), "-o", str(out)]) == 0
    html = out.read_text()
    assert "one panel per level" in html and "draws single-level rooms" not in html
    gif = tmp_path / "office.gif"
    assert main(["animate", str(compared / "eos"), "-o", str(gif), "--max-frames", "2"]) == 0
    assert gif.stat().st_size > 10_000
