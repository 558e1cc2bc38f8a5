"""The run folder's one owner (pedmesh.io.run_folder): its names spelled only there, the
writer protocol declared and checked, and one result type in memory and on disk."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

import pedmesh
from pedmesh.io import run_folder as F
from pedmesh.run.background import BackgroundWriter
from pedmesh.run.memory import MemoryWriter
from pedmesh.run.output import RunWriter
from pedmesh.run.results import RunResult

ROOT = Path(pedmesh.__file__).resolve().parent

#: the names of the folders' files: the constants of run_folder that name a file (the
#: frame folders "density" and "pedestrians" are also field names, so not searched)
NAMES = sorted({v for k, v in vars(F).items() if k.isupper() and isinstance(v, str)
                and "." in v} | set(F.COMPARISON_PLOTS.values()))


def _literals(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every string constant in a module that is exactly a folder's file
    name (docstrings and messages that mention one are prose, not names in use)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return [(n.lineno, n.value) for n in ast.walk(tree)
            if isinstance(n, ast.Constant) and isinstance(n.value, str) and n.value in NAMES]


def test_the_names_are_spelled_in_one_module():
    assert {"summary.json", "evacuation.csv", "outflow_kernel.csv", ".lock",
            "ensemble.csv", "comparison.csv"} <= set(NAMES)
    found = [f"{p.relative_to(ROOT)}:{line}: {text!r}" for p in sorted(ROOT.rglob("*.py"))
             if p.name != "run_folder.py" for line, text in _literals(p)]
    assert found == []


def test_the_name_check_sees_a_literal(tmp_path):
    p = tmp_path / "m.py"
    p.write_text('"""Writes summary.json."""\nx = open("summary.json")\n')
    assert _literals(p) == [(2, "summary.json")]


def test_the_documented_files_are_those_a_rerun_removes():
    """The file list ``pedmesh run --help`` prints and the clean-up list agree."""
    assert set(F.OUTPUT_FILES) <= set(F.RUN_FILES)
    extra = set(F.RUN_FILES) - set(F.OUTPUT_FILES) - set(F.TEMP_FILES)
    assert extra == {F.DENSITY_DIR, F.PEDESTRIANS_DIR, F.LOCK}


@pytest.mark.parametrize("writer", [RunWriter, MemoryWriter])
def test_every_writer_follows_the_declared_protocol(writer):
    assert F.undeclared_methods(writer) == []


def test_the_background_writer_queues_the_declared_writes(tmp_path):
    w = RunWriter(tmp_path / "r", {"model": "sfm"})
    bg = BackgroundWriter(w)
    try:
        for name, kind in F.WRITER_METHODS.items():
            attr = getattr(bg, name)
            if kind == "queued":  # (a stand-in that puts the call on the queue)
                assert getattr(attr, "__self__", None) is not w, name
            elif name != "finish":  # (finish is its own: it drains first)
                assert attr == getattr(w, name), name
    finally:
        bg.finish(status="finished")


def test_an_undeclared_write_method_is_refused_not_run_out_of_order(tmp_path):
    class Extra(RunWriter):
        def extra_write(self, t):  # not declared queued or immediate
            raise AssertionError("ran on the stepping thread")

    assert F.undeclared_methods(Extra) == ["+extra_write"]
    w = Extra(tmp_path / "r", {"model": "sfm"})
    bg = BackgroundWriter(w)
    bg.start()
    try:
        with pytest.raises(TypeError, match="extra_write is not a method of the writer"):
            bg.extra_write(1.0)
        bg.sample(0.0, 0.0)  # (a declared one is queued as before)
    finally:
        bg.finish(status="finished")
    assert (tmp_path / "r" / F.EVACUATION).read_text().splitlines()[1] == "0.000000,0"


def _same(a, b, *, atol: float) -> None:
    if isinstance(a, dict):
        assert sorted(a) == sorted(b)
        for k in a:
            _same(a[k], b[k], atol=atol)
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b)
        for x, y in zip(a, b):
            _same(x, y, atol=atol)
    elif isinstance(a, np.ndarray) and a.dtype.names:
        assert a.dtype.names == b.dtype.names and len(a) == len(b)
        for name in a.dtype.names:
            _same(a[name], b[name], atol=atol)
    elif isinstance(a, np.ndarray) and a.dtype != object:
        assert a.shape == np.shape(b)
        np.testing.assert_allclose(a, b, rtol=1e-5, atol=atol)
    elif isinstance(a, float):
        assert a == pytest.approx(b, rel=1e-5, abs=atol)
    else:
        assert np.array_equal(np.asarray(a, object), np.asarray(b, object)) if isinstance(
            a, np.ndarray) else a == b


@pytest.mark.parametrize("model, t_end", [("sfm", 60.0), ("eos", 60.0)])
def test_simulate_returns_one_type_with_or_without_a_folder(geometries_dir, tmp_path, model,
                                                           t_end):
    room = geometries_dir / "l_shaped.json"
    kw = dict(model=model, preset="paper", t_end=t_end, mesh_options={"max_area": 4.0})
    if model == "sfm":
        kw["seed"] = 3
    mem = pedmesh.simulate(room, **kw)
    disk = pedmesh.simulate(room, out_dir=tmp_path / "run", **kw)
    assert type(mem) is type(disk) is RunResult
    assert mem.path is None and disk.path == tmp_path / "run"
    assert disk.file(F.SUMMARY).is_file() and mem.file(F.SUMMARY) is None
    machine = {"pid", "wall_time_s", "time_split_s"}  # (the process and the clock)
    # (the safety record on disk reads outflow.csv, written with 9 digits)
    _same({k: v for k, v in mem.summary.items() if k not in machine},
          {k: v for k, v in disk.summary.items() if k not in machine}, atol=1e-6)
    for name in ("model", "status", "finished", "times", "settings"):
        assert getattr(mem, name) == getattr(disk, name), name
    # the series and frames: the digits of their files (evacuation 6 decimals,
    # trajectories.txt 0.1 mm, exits.csv 0.1 ms)
    for name, atol in (("evacuation", 1e-6), ("outflow", 1e-6), ("outflow_kernel", 1e-4),
                       ("crossings", 1e-4), ("exit_times", 1e-4), ("density", 1e-6),
                       ("pedestrians", 1e-6), ("trajectories", 6e-5), ("frame_rate", 0.0),
                       ("density_times", 0.0)):
        _same(getattr(mem, name), getattr(disk, name), atol=atol)
    for t in (0.0, 3.3, t_end):
        _same(mem.density_at(t), disk.density_at(t), atol=1e-6)
        _same(mem.density_fields_at(t), disk.density_fields_at(t), atol=1e-6)
    if model == "sfm":
        assert len(mem.exit_times) > 0 and len(mem.trajectories) > 0
        assert len(mem.pedestrians) == len(disk.pedestrians) > 1
    else:
        assert mem.frame_rate is None and len(mem.trajectories) == 0
        assert "rho" in mem.density[-1][2]
