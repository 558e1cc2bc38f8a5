"""The 3-D export: a glTF scene of the room with walls, obstacles, exits and the crowd."""

from __future__ import annotations

import numpy as np
import pytest

from pedmesh.cli import main
from pedmesh.io.export3d import export_room_3d, room_scene

trimesh = pytest.importorskip("trimesh")


def test_glb_round_trip(load_shipped, tmp_path):
    room = load_shipped("pillar_hall.json")
    pos = room.initial_positions()[:50]
    out = export_room_3d(room, tmp_path / "hall.glb", positions=pos, wall_height=3.0)
    scene = trimesh.load(out)
    assert set(scene.geometry) == {"floor", "walls", "obstacles", "exits", "crowd"}
    # glTF is y-up: the room's (x, y, z) is stored as (x, z, -y), which viewers stand upright
    (x0, h0, mz1), (x1, h1, mz0) = scene.bounds
    bx0, by0, bx1, by1 = room.walkable.bounds
    assert (x0, -mz0) == pytest.approx((bx0 - 0.2, by0 - 0.2), abs=1e-5)  # walls 0.2 m thick
    assert (x1, -mz1) == pytest.approx((bx1 + 0.2, by1 + 0.2), abs=1e-5)
    assert h0 == pytest.approx(0.0, abs=1e-9) and h1 == pytest.approx(3.0)
    # each mesh keeps the room's frame (z up); the rotation is on its node
    (gx0, gy0, gz0), (gx1, gy1, gz1) = scene.geometry["walls"].bounds
    assert (gy0, gz0, gy1, gz1) == pytest.approx((by0 - 0.2, 0.0, by1 + 0.2, 3.0), abs=1e-5)
    floor = scene.geometry["floor"]
    assert floor.area == pytest.approx(room.area, rel=1e-6)
    obstacles = scene.geometry["obstacles"]
    footprint = sum(o.shape.area for o in room.obstacles)
    assert obstacles.volume == pytest.approx(3.0 * footprint, rel=1e-6)
    crowd = scene.geometry["crowd"]
    assert len(crowd.split(only_watertight=False)) == 50  # one body per pedestrian
    centres = np.array([b.bounds.mean(axis=0)[:2] for b in crowd.split(only_watertight=False)])
    d = np.linalg.norm(centres[:, None, :] - pos[None, :, :], axis=2).min(axis=1)
    assert d.max() < 1e-5
    # doors: the walls leave the exits open
    import shapely
    from shapely.ops import substring

    walls = scene.geometry["walls"]
    top = walls.faces[np.all(np.isclose(walls.vertices[walls.faces][:, :, 2], 3.0), axis=1)]
    footprint = shapely.union_all(shapely.polygons(walls.vertices[top][:, :, :2]))
    assert footprint.area == pytest.approx(walls.volume / 3.0, rel=1e-6)
    for k in range(len(room.exits)):
        door = substring(shapely.LineString(room.exit_polyline(k)), 0.01, 0.99,
                         normalized=True)
        gap = door.buffer(0.25, cap_style="flat")  # across the wall's thickness
        assert footprint.intersection(gap).area < 1e-9  # the door is open


def test_other_formats_and_errors(load_shipped, tmp_path):
    room = load_shipped("l_shaped.json")
    height_axis = {".gltf": 1, ".obj": 1, ".ply": 2, ".stl": 2}  # y-up as glTF/OBJ readers
    for suffix, axis in height_axis.items():
        p = export_room_3d(room, tmp_path / f"room{suffix}", wall_height=2.0)
        assert p.stat().st_size > 1000
        loaded = trimesh.load(p, force="mesh")
        assert len(loaded.faces) > 100
        lo, hi = loaded.bounds
        assert (lo[axis], hi[axis]) == pytest.approx((0.0, 2.0), abs=1e-6)
        assert not list(tmp_path.glob("*.part"))
    from pedmesh import PedmeshError

    with pytest.raises(PedmeshError, match="unsupported 3-D format"):
        export_room_3d(room, tmp_path / "room.fbx")
    with pytest.raises(PedmeshError, match="wall_height must be a positive"):
        room_scene(room, wall_height=float("nan"))


def test_export_command_with_a_run(geometries_dir, tmp_path, capsys):
    run = tmp_path / "run"
    room = str(geometries_dir / "l_shaped.json")
    assert main(["run", room, "--out", str(run), "-q", "--t-end", "6"]) == 0
    out = tmp_path / "l.glb"
    assert main(["export", room, "-o", str(out), "--run", str(run), "--time", "3"]) == 0
    assert "88 pedestrians at t = 3 s" in capsys.readouterr().out
    assert len(trimesh.load(out).geometry["crowd"].split(only_watertight=False)) == 88
    status = main(["export", str(geometries_dir / "pillar_hall.json"), "-o", str(out),
                   "--run", str(run)])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and "another room file" in err[0]
    status = main(["export", room, "-o", str(out), "--time", "3"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and "--time needs --run" in err[0]
    status = main(["export", room, "-o", str(tmp_path / "x.fbx")])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and "unsupported 3-D format" in err[0]
