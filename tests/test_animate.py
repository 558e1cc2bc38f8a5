"""pedmesh animate: a run's frames as MP4 (the ffmpeg of the imageio-ffmpeg wheel) or GIF."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pedmesh.cli import main


@pytest.fixture(scope="module")
def runs(tmp_path_factory, geometries_dir):
    base = tmp_path_factory.mktemp("anim")
    room = geometries_dir / "l_shaped.json"
    for model in ("sfm", "rdue"):
        assert main(["run", str(room), "--model", model, "--max-area", "4", "--t-end", "12",
                     "--out", str(base / model), "-q"]) == 0
    return base


def test_an_mp4_of_a_social_force_run(runs):
    import imageio_ffmpeg

    out = runs / "sfm.mp4"
    assert main(["animate", str(runs / "sfm"), "-o", str(out), "--fps", "4"]) == 0
    frames = imageio_ffmpeg.read_frames(str(out))
    meta = next(frames)
    pics = [np.frombuffer(f, np.uint8) for f in frames]
    frames_in_run = json.loads((runs / "sfm" / "summary.json").read_text())["frames"]
    assert meta["fps"] == 4 and len(pics) == frames_in_run  # one picture per output frame
    assert all(p.std() > 5 for p in pics)  # not blank
    assert not np.array_equal(pics[0], pics[-1])  # the crowd moves


def test_a_gif_of_a_continuum_run(runs):
    from PIL import Image

    out = runs / "rdue.gif"
    assert main(["animate", str(runs / "rdue"), "-o", str(out), "--max-frames", "5"]) == 0
    im = Image.open(out)
    assert im.n_frames == 5


def test_each_frame_is_read_once(runs, monkeypatch):
    """The first density frame (read at start-up to tell a building from a room) is not
    read again for the first picture."""
    from pedmesh import animate
    from pedmesh.io import vtk

    reads = []
    real = vtk.read_vtu
    monkeypatch.setattr(vtk, "read_vtu", lambda path: reads.append(path) or real(path))
    frames = animate._Frames(runs / "rdue")
    for k in range(3):
        frames.field(k)
    assert len(reads) == 3 and len(set(reads)) == 3


def test_animate_errors_are_one_line(runs, tmp_path, capsys):
    for args, message in (([str(runs / "sfm"), "-o", str(tmp_path / "a.avi")], "use one of"),
                          ([str(tmp_path / "none"), "-o", str(tmp_path / "a.gif")],
                           "no such run folder"),
                          ([str(runs / "sfm"), "-o", str(tmp_path / "a.gif"), "--fps", "0"],
                           "--fps must be between")):
        assert main(["animate", *args]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], err
    assert not list(tmp_path.glob("*.part*"))
