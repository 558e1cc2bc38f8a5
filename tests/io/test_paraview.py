"""The ParaView steps of the README, run by ParaView itself (docs/paraview_check.py under
pvbatch). Skipped where ParaView or xvfb-run is not installed (apt-get install paraview
xvfb)."""

from __future__ import annotations

import shutil
import subprocess
import time
from pathlib import Path

import pytest

from pedmesh.cli import main

SCRIPT = Path(__file__).resolve().parents[2] / "docs" / "paraview_check.py"
pytestmark = pytest.mark.skipif(
    shutil.which("pvbatch") is None or shutil.which("xvfb-run") is None,
    reason="ParaView's pvbatch and xvfb-run are not installed")


def _pvbatch(*args: str) -> subprocess.CompletedProcess:
    """Run the script under xvfb-run; again (up to 3 times) when the virtual X server was
    not ready ('bad X server connection'), a race of xvfb-run's, not of the script."""
    for _ in range(3):
        r = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1280x1024x24", "pvbatch",
                            str(SCRIPT), *args], capture_output=True, text=True, timeout=180)
        if r.returncode == 0 or "X server" not in r.stderr:
            return r
        time.sleep(1.0)
    return r


def _picture_has_content(png: Path, colours: int = 50):
    import matplotlib.image as mpimg

    img = mpimg.imread(png)
    assert img.shape[0] >= 500 and img.shape[1] >= 900
    assert len({tuple(px) for px in img[::7, ::7, :3].reshape(-1, 3)}) > colours  # not blank
    return img


@pytest.mark.parametrize(("model", "field", "extra"), [
    ("sfm", "density", ["--t-end", "20"]),
    ("rdue", "rho", ["--t-end", "10", "--max-area", "2"]),
])
def test_paraview_renders_a_run(geometries_dir, tmp_path, model, field, extra):
    run = tmp_path / model
    assert main(["run", str(geometries_dir / "l_shaped.json"), "--model", model, "--out",
                 str(run), "-q", *extra]) == 0
    png = tmp_path / "view.png"
    r = _pvbatch(str(run), str(png))
    assert r.returncode == 0, r.stderr
    line = r.stdout.strip().splitlines()[-1]
    assert f"{field} in [0, " in line
    hi = float(line.split(f"{field} in [0, ")[1].split("]")[0])
    assert hi > 0.5
    if model == "sfm":
        assert line.endswith("pedestrians") and int(line.split("; ")[1].split()[0]) > 0
    _picture_has_content(png)


def test_paraview_shows_the_mesh_exits(geometries_dir, tmp_path):
    mesh = tmp_path / "hall.vtu"
    assert main(["mesh", str(geometries_dir / "pillar_hall.json"), "-o", str(mesh)]) == 0
    r = _pvbatch("--mesh", str(mesh), str(tmp_path / "mesh.png"))
    assert r.returncode == 0, r.stderr
    n_exit = int(r.stdout.strip().splitlines()[-1].split(", ")[1].split()[0])
    assert n_exit > 0
    img = _picture_has_content(tmp_path / "mesh.png", colours=3)
    green = (img[..., 0] < 0.1) & (img[..., 1] > 0.5) & (img[..., 2] < 0.1)
    assert green.sum() > 20  # the exits, drawn in green


def test_paraview_check_names_a_missing_run(tmp_path):
    r = _pvbatch(str(tmp_path / "nothing"), str(tmp_path / "x.png"))
    assert r.returncode == 2 and "no density.pvd" in r.stderr


def test_paraview_renders_every_level_of_a_building(tmp_path):
    """Issue 45: a building's run is shown in 3-D with every level, not the top floor from
    above (which looked blank)."""
    import json
    import sys

    import numpy as np

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from building_data import TWO

    room = tmp_path / "two.json"
    room.write_text(json.dumps({"format": "pedmesh-room", "version": 1, "units": "m", **TWO}))
    run = tmp_path / "run"
    assert main(["run", str(room), "--out", str(run), "-q", "--t-end", "12"]) == 0
    png = tmp_path / "view.png"
    r = _pvbatch(str(run), str(png), "--time", "6")
    assert r.returncode == 0, r.stderr
    line = r.stdout.strip().splitlines()[-1]
    assert "a building of height 3 m" in line and "pedestrians" in line
    img = _picture_has_content(png)[..., :3]
    # the geometry (not the background, left of the colour bars) spans both floors: much
    # of the picture's height, where a top view of the upper floor covered a band
    body = img[:, : int(0.8 * img.shape[1])]
    background = np.median(body.reshape(-1, 3), axis=0)
    rows = np.flatnonzero((np.abs(body - background).sum(axis=2) > 0.1).any(axis=1))
    assert rows.max() - rows.min() > 0.5 * img.shape[0]
