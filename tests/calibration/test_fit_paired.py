"""The clearance fit compares the Voronoi speeds run by run: a run's realisations pool
their samples, and the runs are weighted by the experiment's samples, not by how long the
simulation lingered in the bin."""

import math

import pytest

from pedmesh.fitting import fit_validated as fv


@pytest.fixture
def clearance():
    fv.configure("clearance")
    yield
    fv.configure("corner")


def _rec(samples):
    """A realisation's record: ``samples[run][rho] = (n_sim, v_sim, n_exp, v_exp)``."""
    rec = {}
    for ent in fv.ENTRANCES:
        t = fv._suffix(ent)
        for run in fv.CORRIDOR_RUNS:
            for d in fv.FD_RHOS:
                n, v, ne, ve = samples.get(run, {}).get(d, (0, math.nan, 0, math.nan))
                key = f"{t}/{run}/rho={d:g}"
                rec.update({f"n_sim{key}": n, f"v_sim{key}": v, f"n_exp{key}": ne,
                            f"v_exp{key}": ve})
    return rec


def test_runs_are_weighted_by_the_experiments_samples_not_the_simulations(clearance):
    a, b = fv.CORRIDOR_RUNS[:2]
    # run a lingers at 2 /m^2 in the first realisation (300 samples), b hardly (20)
    r1 = _rec({a: {2.0: (300, 0.6, 100, 0.62)}, b: {2.0: (20, 0.9, 100, 0.85)}})
    r2 = _rec({a: {2.0: (30, 0.7, 100, 0.62)}, b: {2.0: (200, 1.0, 100, 0.85)}})
    out = {}
    fv._merge_paired(out, [r1, r2])
    t = fv._suffix(fv.ENTRANCES[0])
    va = (300 * 0.6 + 30 * 0.7) / 330
    vb = (20 * 0.9 + 200 * 1.0) / 220
    assert out[f"v_sim{t}/{a}/rho=2"] == pytest.approx(va)
    assert out[f"v_sim_paired{t}/rho=2"] == pytest.approx(0.5 * (va + vb))
    assert out[f"v_exp_paired{t}/rho=2"] == pytest.approx(0.5 * (0.62 + 0.85))
    # a bin no run fills in both: no comparison
    assert math.isnan(out[f"v_sim_paired{t}/rho=3"])
    assert fv.fd_keys(t, 2.0) == (f"v_sim_paired{t}/rho=2", f"v_exp_paired{t}/rho=2")


def test_a_run_with_too_few_samples_does_not_count(clearance):
    from pedmesh.fitting.validate import FD_PAIR_MIN

    a, b = fv.CORRIDOR_RUNS[:2]
    few = FD_PAIR_MIN - 1
    r = _rec({a: {1.0: (500, 1.1, 100, 1.2)}, b: {1.0: (few, 0.2, 100, 1.3)}})
    out = {}
    fv._merge_paired(out, [r, r])
    t = fv._suffix(fv.ENTRANCES[0])
    assert out[f"v_sim_paired{t}/rho=1"] == pytest.approx(1.1)
    assert out[f"v_exp_paired{t}/rho=1"] == pytest.approx(1.2)


def test_the_clearance_law_writes_each_runs_samples(clearance):
    assert fv.PAIRED_FD and fv.FIXED["route_clearance"] == 0.2
    for ent in fv.ENTRANCES:
        t = fv._suffix(ent)
        assert f"v_exp_paired{t}/rho=2" in fv.COLUMNS
        assert f"n_sim{t}/{fv.CORRIDOR_RUNS[-1]}/rho=3" in fv.COLUMNS
    fv.configure("corner")
    assert not fv.PAIRED_FD and "v_sim_paired/rho=2" not in fv.COLUMNS


def test_a_bin_the_simulation_does_not_reach_run_by_run_still_counts(clearance):
    """The experiment has samples at 3 /m^2 but no simulated run has enough there: the
    paired comparison is empty, and the objective counts the bin as missed (as pooled),
    rather than dropping the target."""
    rec = {k: 0.0 for k in fv.COLUMNS if k.startswith(("err/", "J_exit", "Jb_sim", "Jw_sim",
                                                          "rho_front", "stuck"))}
    rec.update({"failed": 0.0, "clogged": 0.0})
    for ent in fv.ENTRANCES:
        t = fv._suffix(ent)
        for d in fv.FD_RHOS:
            rec[f"v_exp{t}/rho={d:g}"] = 1.0
            rec[f"n_sim{t}/rho={d:g}"] = 0.0
            rec[f"v_sim_paired{t}/rho={d:g}"] = rec[f"v_exp_paired{t}/rho={d:g}"] = 1.0
    base = fv.objective(rec)
    t = fv._suffix(fv.ENTRANCES[0])
    rec[f"v_sim_paired{t}/rho=3"] = rec[f"v_exp_paired{t}/rho=3"] = math.nan
    rec[f"err/fd{t}/rho=3"] = math.nan
    assert fv.objective(rec) == pytest.approx(base + (fv.MISSING_FD_ERROR / fv.TOL_FD) ** 2)
    target = next(x for x in fv.targets(rec, None) if x["key"] == f"fd{t}/rho=3")
    assert not target["pass"] and target["ref"] == 1.0


def test_the_report_says_how_long_each_run_stays_at_each_density(clearance):
    """fit.md's table of seconds in each density bin: the simulation's samples over its
    realisations and its trajectory rate, the experiment's over its frame rate (16 /s); a
    run the model never brings to 2 /m^2 shows as 0.0 there."""
    from pedmesh.fitting.validate import TRAJECTORY_RATE_HZ

    a, b = fv.CORRIDOR_RUNS[:2]
    n_real = len(fv.SEEDS)
    rec = _rec({a: {2.0: (0, 0.0, 160, 0.9)},
                b: {1.0: (n_real * 25 * TRAJECTORY_RATE_HZ, 1.2, 320, 1.3)}})
    lines = fv.reach_table(rec)
    cut = lines.index(next(x for x in lines if "mean Voronoi speed" in x))
    row = {(r.split(" | ")[0].strip("| "), r.split(" | ")[1]): r for r in lines[:cut]
           if r.startswith("| ") and " | uo-" in r}
    ent = fv.ENTRANCES[0]
    assert row[ent, a].split(" | ")[3] == "0.0 / 10.0"  # 2 /m^2: never in the model
    assert row[ent, b].split(" | ")[2] == "25.0 / 20.0"  # 1 /m^2
    # the experiment's seconds follow its frame rate
    slow = {(r.split(" | ")[0].strip("| "), r.split(" | ")[1]): r
            for r in fv.reach_table(rec, 8.0)[:cut] if r.startswith("| ") and " | uo-" in r}
    assert slow[ent, a].split(" | ")[3] == "0.0 / 20.0"
    # the second table: each run's speed per bin, "-" where a side has no sample
    speeds = [r for r in lines[cut:] if r.startswith(f"| {ent} | ")]
    row_a = next(r for r in speeds if f" | {a} | " in r)
    row_b = next(r for r in speeds if f" | {b} | " in r)
    assert row_a.split(" | ")[3] == "- / 0.90"  # 2 /m^2: the experiment moving, not the model
    assert row_b.split(" | ")[2] == "1.20 / 1.30"
    fv.configure("corner")
    assert fv.reach_table(rec) == []


def _scored_record():
    """A record of the running law whose every error is 0 and whose speeds agree."""
    rec = {k: 0.0 for k in fv.COLUMNS if k.startswith(("err/", "J_exit", "Jb_sim", "Jw_sim",
                                                          "rho_front", "stuck"))}
    rec.update({n: 0.5 for n in fv.NAMES})
    rec.update({"failed": 0.0, "clogged": 0.0, "seconds": 1.0, "rms_all": 0.0})
    for ent in fv.ENTRANCES:
        t = fv._suffix(ent)
        for d in fv.FD_RHOS:
            rec[f"v_exp{t}/rho={d:g}"] = rec[f"v_sim{t}/rho={d:g}"] = 1.0
            rec[f"n_sim{t}/rho={d:g}"] = 100.0
            rec[f"v_sim_paired{t}/rho={d:g}"] = rec[f"v_exp_paired{t}/rho={d:g}"] = 1.0
    return rec


def test_the_pooled_law_also_scores_the_issues_pooled_speeds(tmp_path):
    """Run by run the model matches (it reaches 2 /m^2 only where the experiment queues);
    pooled it is 30 % slow there. The clearance law does not see it; clearance_pooled
    counts it, and re-scores the clearance fit's rows it reuses."""
    fv.configure("clearance")
    try:
        rec = _scored_record()
        t = fv._suffix(fv.ENTRANCES[0])
        rec[f"v_sim{t}/rho=2"] = 0.7
        base = fv.objective(rec)
        assert base == pytest.approx(0.0)
        old = tmp_path / "clearance.csv"
        fv.Log(old).add(rec, "nm")
        fv.configure("clearance_pooled")
        assert fv.PAIRED_FD and fv.POOLED_TOO
        assert f"err/fd_pooled{t}/rho=2" in fv.COLUMNS
        log = fv.Log(tmp_path / "pooled.csv", reuse=[old])
        (row,) = log.order
        assert row["phase"] == "reused"
        assert row[f"err/fd_pooled{t}/rho=2"] == pytest.approx(-0.3)
        assert row["objective"] == pytest.approx((0.3 / fv.TOL_FD) ** 2)
        target = next(x for x in fv.targets(row, None) if x["key"] == f"fd_pooled{t}/rho=2")
        assert not target["pass"] and target["sim"] == pytest.approx(0.7)
        # a new row is numbered after the reused ones and goes to the law's own file
        new = log.add({**_scored_record(), fv.NAMES[0]: 0.6}, "nm")
        assert new["eval"] == 2 and (tmp_path / "pooled.csv").is_file()
        # reopened (a resumed fit): the reused row, then the law's own, their F as written
        again = fv.Log(tmp_path / "pooled.csv", reuse=[old])
        assert [(int(r["eval"]), r["phase"]) for r in again.order] == [(1, "reused"),
                                                                       (2, "nm")]
        assert again.order[1]["objective"] == pytest.approx(new["objective"])
        # the other fit goes on (its row #2): frozen at its first row, the reuse ignores it
        fv.configure("clearance")
        fv.Log(old).add({**rec, fv.NAMES[0]: 0.7}, "nm")
        fv.configure("clearance_pooled")
        frozen = fv.Log(tmp_path / "pooled.csv", reuse=[old], reuse_upto=1)
        assert [int(r["eval"]) for r in frozen.order] == [1, 2]
        assert frozen.add({**_scored_record(), fv.NAMES[0]: 0.8}, "nm")["eval"] == 3
        # unfrozen, numbers still never repeat: a new row is numbered after the largest
        loose = fv.Log(tmp_path / "pooled.csv", reuse=[old])
        assert loose.add({**_scored_record(), fv.NAMES[0]: 0.9}, "nm")["eval"] == 4
    finally:
        fv.configure("corner")


def test_the_pooled_laws_merge_writes_the_pooled_errors():
    """merge() of a clearance_pooled point's realisations gives the pooled errors the
    objective reads (the pooled speeds: every run's samples of both realisations)."""
    fv.configure("clearance_pooled")
    try:
        recs = []
        for v in (0.6, 0.8):  # two realisations, each with every run's samples
            r = _rec({})
            r.update({k: 0.0 for k in fv.COLUMNS if k.startswith(("J_exit", "Jb_sim",
                                                                    "Jw_sim", "rho_front",
                                                                    "stuck"))})
            r.update({"failed": 0.0, "clogged": 0.0, "seconds": 1.0, "rms_all": 0.0})
            for ent in fv.ENTRANCES:
                t = fv._suffix(ent)
                for d in fv.FD_RHOS:
                    r.update({f"v_sim{t}/rho={d:g}": v, f"n_sim{t}/rho={d:g}": 100.0,
                              f"v_exp{t}/rho={d:g}": 1.0})
            recs.append(r)
        out = fv.merge(recs)
        t = fv._suffix(fv.ENTRANCES[0])
        assert out[f"err/fd_pooled{t}/rho=2"] == pytest.approx(-0.3)
        assert math.isfinite(fv.objective(out))
    finally:
        fv.configure("corner")
