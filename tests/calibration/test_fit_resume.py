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


def test_rows_are_appended_in_the_files_column_order_and_other_columns_refused(tmp_path,
                                                                              monkeypatch):
    import csv

    fv.configure("corner")
    rec = {c: 1.0 for c in fv.COLUMNS}
    rec.update({n: 0.5 + 0.01 * i for i, n in enumerate(fv.NAMES)})
    rec.update({"failed": 0.0, "clogged": 0.0})
    path = tmp_path / "evals.csv"
    path.write_text(",".join(reversed(fv.COLUMNS)) + "\n")  # (an older fit's order)
    log = fv.Log(path)
    monkeypatch.setattr(fv, "objective", lambda r: 7.0)  # (not a real evaluation)
    log.add(rec, "nm")
    row = next(csv.DictReader(path.open()))
    assert row["objective"] == "7.0" and row[fv.NAMES[0]] == "0.5"
    fresh = tmp_path / "new.csv"  # (a new file: one header, then the rows)
    log = fv.Log(fresh)
    for i in range(2):
        log.add({**rec, fv.NAMES[0]: 0.6 + 0.01 * i}, "nm")
    lines = fresh.read_text().splitlines()
    assert len(lines) == 3 and lines[0] == ",".join(fv.COLUMNS)
    path.write_text(",".join(fv.COLUMNS[:-1] + ["something else"]) + "\n")
    with pytest.raises(SystemExit, match="other columns than this fit writes"):
        fv.Log(path).check_writable()
    with pytest.raises(SystemExit, match="other columns than this fit writes"):
        fv.Log(path).add(rec, "nm")


def test_a_probe_is_an_evaluation_with_some_fitted_parameters_changed(tmp_path):
    fv.configure("corner")
    try:
        log = fv.Log(tmp_path / "none.csv")
        for i, f in enumerate((6.0, 5.0), start=1):
            rec = {n: fv.FIT[n]["grid"][0] for n in fv.NAMES}
            rec.update({"eval": float(i), "phase": "nm", "objective": f,
                        fv.NAMES[0]: fv.FIT[fv.NAMES[0]]["grid"][0] + 0.001 * i})
            log.order.append(rec)
        a, b = fv.NAMES[:2]
        lo, hi = fv.FIT[b]["bounds"]
        x = fv.probe_point(log, [f"{b}={0.5 * (lo + hi)}"])  # from the best (#2)
        assert x[a] == pytest.approx(log.order[1][a]) and x[b] == pytest.approx(0.5 * (lo + hi))
        assert fv.probe_point(log, [], 1)[a] == pytest.approx(log.order[0][a])
        with pytest.raises(SystemExit, match="not a fitted parameter"):
            fv.probe_point(log, ["nonsense=1"])
        with pytest.raises(SystemExit, match="outside"):
            fv.probe_point(log, [f"{b}={hi + 1}"])
        with pytest.raises(SystemExit, match="not a number"):
            fv.probe_point(log, [f"{b}=x"])
    finally:
        fv.configure("corner")
