"""Start-area populations (pedmesh.population): distributions in room files, seeded draws,
premovement in the social force and continuum models, per-agent speeds and radii, exit
assignment."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pedmesh import Room
from pedmesh.cli import main
from pedmesh.errors import GeometryError
from pedmesh.population import distribution_from_spec, draw_population
from pedmesh.mesh import triangulate


def corridor(x0=12.0, x1=18.0, **area):
    """A 30 x 4 m corridor with an exit at each end and a crowd in its middle (x0 to x1)."""
    return Room(outline=[(0, 0), (30, 0), (30, 4), (0, 4)],
                exits=[{"name": "west", "polyline": [(0, 0), (0, 4)]},
                       {"name": "east", "polyline": [(30, 0), (30, 4)]}],
                start_areas=[{"name": "crowd", "polygon": [(x0, 0), (x1, 0), (x1, 4), (x0, 4)],
                              "spacing": 1.0, **area}])


# ------------------------------------------------------------------ specifications
@pytest.mark.parametrize("spec, mean", [
    (5.0, 5.0),
    ({"distribution": "uniform", "min": 10, "max": 20}, 15.0),
    ({"distribution": "normal", "mean": 1.34, "sd": 0.26, "min": 0.0}, 1.34),
    ({"distribution": "lognormal", "mu": np.log(30.0), "sigma": 0.5}, 30 * np.exp(0.125)),
])
def test_distributions_draw_what_they_say(spec, mean):
    d = distribution_from_spec(spec, "premovement", "start area 'a'")
    x = d.sample(np.random.default_rng(1), 40_000)
    assert abs(x.mean() - mean) < 0.02 * mean
    assert abs(d.mean_value - mean) < 1e-3 * mean
    assert distribution_from_spec(d.to_spec(), "premovement", "a") == d


def test_truncation_keeps_values_inside_and_renormalises():
    d = distribution_from_spec({"distribution": "normal", "mean": 1.34, "sd": 0.26,
                                "min": 1.0, "max": 1.6}, "speed", "a", positive=True)
    x = d.sample(np.random.default_rng(2), 20_000)
    assert x.min() >= 1.0 and x.max() <= 1.6
    assert d.cdf(1.0) == pytest.approx(0.0, abs=1e-12) and d.cdf(1.6) == pytest.approx(1.0)
    ln = distribution_from_spec({"distribution": "lognormal", "mu": 3.0, "sigma": 1.0,
                                 "max": 60.0}, "premovement", "a")
    y = ln.sample(np.random.default_rng(3), 20_000)
    assert y.max() <= 60.0 and ln.cdf(60.0) == pytest.approx(1.0)


@pytest.mark.parametrize("spec, match", [
    ({"distribution": "gamma", "k": 2}, "unknown distribution 'gamma'"),
    ({"distribution": "uniform", "min": 5}, "needs 'max'"),
    ({"distribution": "uniform", "min": 5, "max": 5}, "'max' must exceed 'min'"),
    ({"distribution": "normal", "mean": 1.3, "sd": 0.2}, "needs a 'min'"),
    ({"distribution": "normal", "mean": 1.3, "sd": -0.2, "min": 0}, "'sd' must be positive"),
    ({"distribution": "uniform", "min": -1, "max": 5}, "values must be >= 0"),
    ({"distribution": "uniform", "min": 0, "max": 5, "mode": 1}, "unknown key 'mode'"),
    ("fast", "must be a number or an object"),
    ({"distribution": "normal", "mean": 1.3, "sd": 0.1, "min": 5.0, "max": 6.0},
     "no mass between"),
])
def test_bad_distributions_are_clear_errors(spec, match):
    with pytest.raises(GeometryError, match=match):
        corridor(premovement=spec)


def test_bad_radius_and_exits():
    with pytest.raises(GeometryError, match="'radius': values must be positive"):
        corridor(radius=0.0)
    with pytest.raises(GeometryError, match="names 'north', which is not an exit"):
        corridor(exits=["north"])
    with pytest.raises(GeometryError, match="must add up to 1, got 0.9"):
        corridor(exits={"west": 0.4, "east": 0.5})


def test_bad_distribution_in_a_room_file_is_one_line(tmp_path, capsys):
    data = {"outline": [[0, 0], [10, 0], [10, 4], [0, 4]],
            "exits": [{"name": "e", "polyline": [[10, 0], [10, 4]]}],
            "start_areas": [{"name": "a", "polygon": [[1, 1], [4, 1], [4, 3], [1, 3]],
                             "spacing": 1, "speed": {"distribution": "uniform", "min": 1.5,
                                                     "max": 1.0}}]}
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    assert main(["run", str(path), "--model", "sfm", "-q", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.json" in err[0] and "start area 'a': 'speed'" in err[0]


def test_room_file_round_trip(tmp_path):
    from pedmesh.io import load_room, save_room

    room = corridor(premovement={"distribution": "uniform", "min": 0, "max": 30},
                    speed={"distribution": "normal", "mean": 1.34, "sd": 0.26, "min": 0.5},
                    radius=0.2, exits={"west": 0.25, "east": 0.75})
    again = load_room(save_room(room, tmp_path / "r.json"))
    assert again == room
    listed = corridor(exits=["east", "west"])
    assert load_room(save_room(listed, tmp_path / "l.json")) == listed


# ------------------------------------------------------------------ draws
def test_draws_are_reproducible_and_independent_per_quantity():
    room = corridor(premovement={"distribution": "uniform", "min": 0, "max": 30},
                    exits={"west": 0.25, "east": 0.75})
    a, b = draw_population(room, seed=7), draw_population(room, seed=7)
    assert np.array_equal(a.premovement, b.premovement) and np.array_equal(a.target, b.target)
    c = draw_population(room, seed=8)
    assert not np.array_equal(a.premovement, c.premovement)
    # adding a speed distribution does not change the premovement draws
    more = corridor(premovement={"distribution": "uniform", "min": 0, "max": 30},
                    exits={"west": 0.25, "east": 0.75}, speed=1.2)
    assert np.array_equal(draw_population(more, seed=7).premovement, a.premovement)
    # exact quotas: 24 people, a quarter to the west
    counts = {t: int((a.target == k).sum()) for k, t in enumerate(a.targets)}
    assert counts[("west",)] == 6 and counts[("east",)] == 18


# ------------------------------------------------------------------ the social force model
def _sfm(room, seed=0, t_end=None, **over):
    from pedmesh.models.sfm.adapter import SFMRun

    mesh = triangulate(room, max_area=1.0)
    run = SFMRun(room, mesh, over, seed=seed)
    return run


def test_premovement_delays_each_start_by_its_drawn_time():
    # one row across the corridor, all heading east: nobody walks into someone waiting (in
    # a crowd, those who start do push those still waiting)
    room = corridor(14.5, 15.5, premovement={"distribution": "uniform", "min": 1.0, "max": 4.0},
                    exits=["east"])
    run = _sfm(room, seed=3)
    sim = run.sim
    tpre = dict(zip(sim.ids[:sim.n].tolist(), sim.tpre[:sim.n].tolist()))
    x0 = {i: p for i, p in zip(sim.ids[:sim.n].tolist(), sim.x[:sim.n].copy())}
    started = {}
    while sim.t < 6.0:
        sim.step()
        for i, p in zip(sim.ids[:sim.n].tolist(), sim.x[:sim.n]):
            # (along the corridor: the walls push the outer two sideways from the start)
            if i not in started and p[0] - x0[i][0] > 0.05:
                started[i] = sim.t
    assert len(started) == len(tpre)  # everyone walks by 6 s
    late = [started[i] - tpre[i] for i in started]
    assert min(late) >= 0.0  # nobody moves 5 cm before their premovement time
    assert max(late) < 0.5  # and everyone within half a second after it


def test_exit_assignment_is_respected():
    room = corridor(exits={"west": 0.25, "east": 0.75})
    run = _sfm(room, seed=5)
    sim = run.sim
    target = {i: sim.toff[k] // triangulate(room, max_area=1.0).n_triangles
              for k, i in enumerate(sim.ids[:sim.n].tolist())}
    groups = run.sim._targets
    sim.run(60.0)
    assert sim.n == 0
    names = run.mesh.exit_names
    for i, g in target.items():
        assert names[sim.exit_id[i]] == groups[g][0]
    assert np.sum(sim.exit_id == names.index("west")) == 6


def test_exits_as_a_list_take_the_quickest_of_them():
    room = corridor(exits=["east"])
    run = _sfm(room)
    run.sim.run(60.0)
    assert run.sim.n == 0 and np.all(np.array(run.mesh.exit_names)[run.sim.exit_id] == "east")


def test_free_speeds_and_radii_per_person():
    room = corridor(speed={"distribution": "uniform", "min": 0.6, "max": 1.4}, radius=0.22)
    run = _sfm(room, seed=1, speed_law="exponential", beta=1e-3)  # (U_e within 0.5 % of U_f)
    sim = run.sim
    assert np.all(sim.rad == 0.22) and 0.6 <= sim.u0.min() and sim.u0.max() <= 1.4
    for _ in range(400):  # 4 s: everyone near their free speed (tau = 0.5 s)
        sim.step()
    u = {i: np.hypot(*v) for i, v in zip(sim.ids[:sim.n].tolist(), sim.v[:sim.n])}
    u0 = dict(zip(sim.ids[:sim.n].tolist(), sim.u0[:sim.n].tolist()))
    err = np.array([u[i] / u0[i] - 1 for i in u])
    assert np.median(np.abs(err)) < 0.05
    p = run.parameters()["population"]
    assert p["radius_m"] == [0.22, 0.22, 0.22] and p["exit_groups"] == {"any": 24}


def test_overlapping_large_bodies_are_refused():
    from pedmesh.errors import SimulationError

    room = corridor(radius=0.6)  # 1.2 m bodies on a 1 m lattice
    with pytest.raises(SimulationError, match="overlap"):
        _sfm(room)


# ------------------------------------------------------------------ continuum models
@pytest.mark.parametrize("model", ["rdue", "eos"])
def test_continuum_premovement_is_a_delayed_source(model):
    from pedmesh.models import get_model

    pre = corridor(premovement={"distribution": "uniform", "min": 5.0, "max": 10.0},
                   speed=1.2)
    mesh = triangulate(pre, max_area=1.0)
    run = get_model(model).build(pre, mesh, {})
    assert run.n_initial == pytest.approx(24.0, rel=1e-9) and run.waiting == run.n_initial
    assert any("'speed' is not used" in w for w in run.warnings)
    inside = []
    while run.t < 12.0:
        run.step(12.0)
        walking = run.solver.mass(run.state.Q)
        inside.append((run.t, walking, run.waiting))
        assert abs(walking + run.waiting + run.evacuated - run.n_initial) < 1e-9
    for t, walking, waiting in inside:
        if t <= 5.0:
            assert walking == 0.0
        if t >= 10.0:
            assert waiting == 0.0
        if 5.0 < t < 10.0:
            assert waiting == pytest.approx(24.0 * (10.0 - t) / 5.0, rel=1e-9)
    assert run.max_mass_error < 1e-12


# ------------------------------------------------------------------ entrances (arrivals)
def entrance_room(arrivals, count=None, crowd=True):
    """A 12 x 3 m corridor with its exit at x = 12, an entrance strip at its west end and
    (``crowd``) ten people standing half way."""
    gate = {"name": "gate", "polygon": [(0.1, 0.1), (0.6, 0.1), (0.6, 2.9), (0.1, 2.9)],
            "arrivals": arrivals}
    if count is not None:
        gate["count"] = count
    areas = [gate]
    if crowd:
        areas.append({"name": "crowd", "polygon": [(5, 0.5), (7, 0.5), (7, 2.5), (5, 2.5)],
                      "count": 10})
    return Room(outline=[(0, 0), (12, 0), (12, 3), (0, 3)],
                exits=[{"name": "east", "polyline": [(12, 0), (12, 3)]}], start_areas=areas)


def test_arrival_schedules():
    from pedmesh.population import Arrivals

    room = entrance_room({"rate": 2.0, "start": 1.5}, count=5, crowd=False)
    arr = room.start_areas[0].arrivals
    assert isinstance(arr, Arrivals) and arr.times == (1.5, 2.0, 2.5, 3.0, 3.5)
    assert arr.cdf([1.4, 1.5, 2.9, 10.0]).tolist() == [0.0, 0.2, 0.6, 1.0]
    timed = entrance_room({"times": [0, 0.3, 0.3, 4]}, crowd=False)
    assert timed.start_areas[0].count == 4
    pop = draw_population(timed, seed=3)
    assert pop.arrival.tolist() == [0, 0.3, 0.3, 4] and pop.has_arrivals
    assert np.isnan(draw_population(corridor()).arrival).all()


@pytest.mark.parametrize("area, match", [
    ({"arrivals": {"rate": 2.0}}, "a 'rate' needs the area's 'count'"),
    ({"arrivals": {"rate": -1.0}, "count": 3}, "'rate' must be positive"),
    ({"arrivals": {"rate": 1.0, "start": -2}, "count": 3}, "'start' must be >= 0"),
    ({"arrivals": {"times": [2, 1]}}, "ascending"),
    ({"arrivals": {"times": [0, 1]}, "count": 3}, "2 times for a 'count' of 3"),
    ({"arrivals": {"rate": 1, "times": [0]}, "count": 1}, "either 'rate'"),
    ({"arrivals": {"rate": 1, "every": 2}, "count": 1}, "unknown key 'every'"),
    ({"arrivals": {"rate": 1}, "spacing": 1.0}, "takes 'count', not 'spacing'"),
    ({"arrivals": {"rate": 1}, "count": 2, "premovement": 3.0},
     "either 'premovement' or 'arrivals'"),
])
def test_bad_arrivals_are_clear_errors(area, match):
    spec = {"name": "gate", "polygon": [(1, 1), (2, 1), (2, 2), (1, 2)], **area}
    with pytest.raises(GeometryError, match=match):
        Room(outline=[(0, 0), (10, 0), (10, 4), (0, 4)],
             exits=[{"name": "e", "polyline": [(10, 0), (10, 4)]}], start_areas=[spec])


def test_entrance_room_file_round_trip(tmp_path):
    from pedmesh.io import load_room, save_room

    for arrivals, count in (({"rate": 1.5, "start": 2.0}, 6), ({"times": [0.0, 0.5, 3.25]},
                                                                None)):
        room = entrance_room(arrivals, count)
        assert load_room(save_room(room, tmp_path / "e.json")) == room


def test_entrance_people_arrive_on_time_and_only_where_there_is_room():
    # 20 people at 2 /s from t = 1 s: nobody is in the room before their time, each
    # enters inside the strip, never overlapping anyone, and all of them leave
    room = entrance_room({"rate": 2.0, "start": 1.0}, count=20)
    run = _sfm(room, seed=0)
    sim = run.sim
    assert sim.n == 10 and sim.n_waiting == 20 and run.remaining == 30
    arrival = run.population.arrival
    seen: dict[int, float] = {}
    while not run.done and sim.t < 60.0:
        sim.step()
        for k, i in enumerate(sim.ids[:sim.n].tolist()):
            if i not in seen and np.isfinite(arrival[i]):
                seen[i] = sim.t
                x, y = sim.x[k]
                assert 0.1 <= x <= 0.6 + 0.2 and 0.1 <= y <= 2.9  # in (or just past) the strip
        x = sim.x[:sim.n]
        if len(x) < 2:
            continue
        d = np.hypot(*(x[:, None, :] - x[None, :, :]).transpose(2, 0, 1))
        np.fill_diagonal(d, np.inf)
        r = sim.rad[:sim.n]
        assert (d - r[:, None] - r[None, :]).min() > -0.05  # no one lands on anyone
    assert run.done and sim.n_evacuated == 30
    late = np.array([seen[i] - arrival[i] for i in seen])
    assert len(seen) == 20 and late.min() >= 0.0  # nobody before their time
    assert np.median(late) < 0.05  # at 2 /s on a 3 m strip there is room at once


def test_a_blocked_entrance_waits():
    # people arrive at 20 /s into a strip with three spots: they enter only as the
    # spots clear, in the order of their times, so they come in later than scheduled
    room = Room(outline=[(0, 0), (12, 0), (12, 1.2), (0, 1.2)],
                exits=[{"name": "east", "polyline": [(12, 0), (12, 1.2)]}],
                start_areas=[{"name": "gate", "polygon": [(0.1, 0.1), (0.5, 0.1), (0.5, 1.1),
                                                          (0.1, 1.1)], "count": 30,
                              "arrivals": {"rate": 20.0}}])
    run = _sfm(room)
    sim = run.sim
    order = []
    while not run.done and sim.t < 80.0:
        sim.step()
        order += [i for i in sim.ids[:sim.n].tolist() if i not in order]
    assert run.done and sorted(order) == order  # first come, first in
    assert np.nanmax(sim.exit_time) > 30 / 20.0 + 12 / 1.34 + 2.0  # held up at the strip


@pytest.mark.parametrize("model", ["rdue", "eos"])
def test_continuum_entrance_is_a_delayed_source(model):
    from pedmesh.models import get_model

    room = entrance_room({"rate": 2.0, "start": 1.0}, count=10, crowd=False)
    run = get_model(model).build(room, triangulate(room, max_area=0.5), {})
    assert run.n_initial == pytest.approx(10.0, rel=1e-9) and run.waiting == run.n_initial
    while run.t < 8.0:
        run.step(8.0)
        expected = 10.0 - min(max(np.floor((run.t - 1.0) * 2.0 + 1e-9) + 1, 0), 10)
        assert run.waiting == pytest.approx(expected, abs=1e-9)
        assert abs(run.solver.mass(run.state.Q) + run.waiting + run.evacuated
                   - run.n_initial) < 1e-9


def test_entrance_seeds_give_realisations_and_repeat():
    room = entrance_room({"rate": 3.0}, count=15, crowd=False)

    def exits(seed):
        run = _sfm(room, seed=seed)
        run.sim.run(40.0)
        assert run.done
        return np.sort(run.sim.exit_time)

    a, b = exits(1), exits(1)
    assert np.array_equal(a, b)  # same seed, same run
    assert not np.array_equal(a, exits(2))  # another seed, another realisation


def test_desired_directions_follow_each_ones_exits():
    # people assigned to the west exit want to go west, the others east, wherever they stand
    room = corridor(exits={"west": 0.5, "east": 0.5})
    run = _sfm(room, seed=2)
    sim = run.sim
    groups = sim.toff[:sim.n] // triangulate(room, max_area=1.0).n_triangles
    west = np.array([sim._targets[g] == ("west",) for g in groups])
    assert 0 < west.sum() < sim.n
    e = sim.desired_directions()
    assert np.all(e[west, 0] < -0.5) and np.all(e[~west, 0] > 0.5)
