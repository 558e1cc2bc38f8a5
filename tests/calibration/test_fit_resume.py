"""fit_validated's Nelder-Mead starts where an interrupted fit started, so a rerun replays
its path from the evaluation log instead of building a new simplex around a later best."""

import pytest

from pedmesh.fitting import fit_validated as fv


def _log(tmp_path, objectives):
    log = fv.Log(tmp_path / "none.csv")  # (no file: an empty log)
    for i, (phase, f) in enumerate(objectives, start=1):
        log.order.append({"eval": float(i), "phase": phase, "objective": f})
    return log


def test_the_default_start_is_the_best_grid_point_not_the_best_so_far(tmp_path):
    log = _log(tmp_path, [("grid", 6.0), ("grid", 5.5), ("nm", 5.0), ("nm", 4.0)])
    assert fv.nm_start(log)["eval"] == 2
    assert fv.nm_start(log, 3)["eval"] == 3


def test_an_unknown_start_is_refused(tmp_path):
    log = _log(tmp_path, [("grid", 6.0)])
    with pytest.raises(SystemExit, match="--nm-from 7: no such evaluation"):
        fv.nm_start(log, 7)
