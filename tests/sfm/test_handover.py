"""Taking people out of a social force run and bringing them back (the hybrid model's
hand-over, issue 47): every person is inside, withdrawn or out at every step, with their
attributes kept by id, and nobody enters where there is no room."""

from __future__ import annotations

import numpy as np
import pytest

from pedmesh import Exit, Room, StartArea
from pedmesh.errors import SimulationError
from pedmesh.mesh import triangulate
from pedmesh.models.sfm import Simulation
from pedmesh.population import Population


@pytest.fixture(scope="module")
def corridor():
    room = Room([(0, 0), (20, 0), (20, 4), (0, 4)], exits=[Exit("out", [(20, 0), (20, 4)])],
                start_areas=[StartArea("crowd", [(1, 0.5), (9, 0.5), (9, 3.5), (1, 3.5)],
                                       count=60)])
    return triangulate(room, max_area=0.5)


def test_withdraw_and_enter_keep_every_person(corridor):
    sim = Simulation(corridor, seed=3)
    N = sim.n_initial
    rng = np.random.default_rng(0)
    out_ids, out_x, out_v = [], [], []
    came_back = 0
    for step in range(int(round(15.0 / sim.numerics.dt))):  # 15 s
        sim.step()
        if step % 20 == 5 and sim.n:
            ids, x, v = sim.withdraw(rng.random(sim.n) < 0.2)
            out_ids += list(ids)
            out_x += list(x)
            out_v += list(v)
        if step % 20 == 15 and out_ids:
            ent = sim.enter(np.array(out_ids), np.array(out_x), np.array(out_v))
            came_back += int(ent.sum())
            out_ids = [i for i, e in zip(out_ids, ent) if not e]
            out_x = [p for p, e in zip(out_x, ent) if not e]
            out_v = [p for p, e in zip(out_v, ent) if not e]
        inside = sim.active_ids
        gone = np.flatnonzero(np.isfinite(sim.exit_time))
        # each id in exactly one place: inside, withdrawn, or out
        everyone = np.concatenate([inside, np.array(out_ids, np.int64), gone])
        assert len(everyone) == N and len(np.unique(everyone)) == N
        assert sim.n_withdrawn == len(out_ids)
        assert sim.n + sim.n_withdrawn + sim.n_evacuated == N
        assert sim.n_evacuated == len(gone)
        assert np.all(np.isfinite(sim.positions))
    assert sim.n_evacuated > 0 and came_back > 10


def test_enter_needs_room_and_a_withdrawn_person(corridor):
    sim = Simulation(corridor, seed=1)
    sim.step()
    x0 = sim.positions
    mask = np.zeros(sim.n, bool)
    mask[:2] = True
    ids, x, v = sim.withdraw(mask)
    r = sim.params.r
    # on top of someone: refused; outside the mesh: refused; at its own old spot: fine
    taken = sim.positions[0]
    ent = sim.enter(ids, np.array([taken, [30.0, 2.0]]), v)
    assert not ent.any() and sim.n_withdrawn == 2
    ent = sim.enter(ids, x, np.zeros((2, 2)))
    assert ent.all() and sim.n_withdrawn == 0 and sim.n == len(x0)
    assert np.all(sim.rad[:sim.n] == r)
    with pytest.raises(SimulationError, match="withdraw"):
        sim.enter(ids[:1], x[:1], v[:1])  # (already inside)
    with pytest.raises(SimulationError, match="one flag per person"):
        sim.withdraw(np.zeros(sim.n + 1, bool))


def test_a_returning_person_keeps_their_attributes(corridor):
    n = 60
    pop = Population(speed=np.linspace(1.0, 1.6, n), radius=np.full(n, 0.2),
                     premovement=np.zeros(n), target=np.zeros(n, np.int64), targets=[()],
                     arrival=np.full(n, np.nan), area=np.zeros(n, np.int64))
    sim = Simulation(corridor, population=pop, seed=2)
    sim.step()
    mask = sim.active_ids == 7
    ids, x, v = sim.withdraw(mask)
    assert list(ids) == [7]
    assert sim.enter(ids, x, v).all()
    row = int(np.flatnonzero(sim.active_ids == 7)[0])
    assert sim.rad[row] == 0.2 and sim.u0[row] == pytest.approx(1.0 + 0.6 * 7 / 59)
