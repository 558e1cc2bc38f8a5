"""Full paper examples with the continuum models (slow: ``pytest -m slow``)."""

from __future__ import annotations

import numpy as np
import pytest

from pedmesh.macro.run import MacroRun

pytestmark = pytest.mark.slow

PARAMS = {"rdue": {"U_f", "beta"}, "pw": {"c0", "U_f", "beta", "tau", "rho_cut", "u_max"}}


def _run(room, model, overrides=None, t_end=600.0):
    run = MacroRun(room, room.mesh(), overrides or {}, model=model, model_params=PARAMS[model])
    while not run.done and run.t < t_end:
        run.step()
        assert run.state.Q[:, 0].min() >= 0.0
    return run


@pytest.mark.parametrize("name", ["example1.json", "example2.json", "example3.json"])
def test_rdue_paper_examples(load_shipped, name):
    room = load_shipped(name)
    run = _run(room, "rdue")
    s = run.summary()
    t = np.asarray(run._curve_t)
    n = np.asarray(run._curve_n)
    t1 = t[np.flatnonzero(n >= 0.01 * 2400)[0]]
    print(f"\nrdue {name}: T50 {s['t_evac_50']:.1f} T90 {s['t_evac_90']:.1f} "
          f"T100 {s['t_evac_100']:.1f} s, first 1 % at {t1:.1f} s, {s['steps']} steps, "
          f"mass error {s['mass_error_max']:.1e}")
    assert run.done
    assert s["mass_error_max"] <= 1e-10
    if name == "example2.json":
        # no characteristic is faster than U_f: the front is 52 m from the exit
        assert t1 >= 47.0


@pytest.mark.parametrize("exit_kind", ["vacuum", "transmissive"])
def test_pw_example2(load_shipped, exit_kind):
    room = load_shipped("example2.json")
    run = _run(room, "pw", {"c0": 1.0, "exit": exit_kind}, t_end=900.0)
    s = run.summary()
    print(f"\npw c0=1 {exit_kind}: T50 {s['t_evac_50']:.1f} T90 {s['t_evac_90']:.1f} "
          f"T100 {s['t_evac_100']:.1f} s, {s['steps']} steps, mass error {s['mass_error_max']:.1e}")
    assert run.done
    assert s["mass_error_max"] <= 1e-10
