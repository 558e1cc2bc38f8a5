"""The compiled pair and wall forces against direct formulas written here."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from pedmesh import Exit, Obstacle, Room
from pedmesh.models.sfm import SocialForceParams
from pedmesh.models.sfm import kernels as K
from pedmesh.models.sfm.walls import WallSet
from pedmesh.mesh import triangulate

P = SocialForceParams()


def direct_pairs(x, v, rc_f, rc_d, p=P):
    """O(N^2) pair accelerations and kernel densities, straight from the paper's formulas."""
    n = len(x)
    F = np.zeros((n, 2))
    rho = np.full(n, 1.0 / (math.pi * p.R**2))  # the pedestrian itself (j = i)
    rij = 2 * p.r
    for i in range(n):
        for j in range(n):
            if i == j:
                continue
            d = float(np.hypot(*(x[i] - x[j])))
            if d < rc_d:
                rho[i] += math.exp(-(d / p.R) ** 2) / (math.pi * p.R**2)
            if d < rc_f:
                nij = (x[i] - x[j]) / d
                tij = np.array([-nij[1], nij[0]])
                g = max(rij - d, 0.0)
                f = (p.A * math.exp((rij - d) / p.B) + p.k * g) * nij \
                    + p.kappa * g * np.dot(v[j] - v[i], tij) * tij
                F[i] += f / p.m
    return F, rho


def kernel_pairs(x, v, rc_f, rc_d, p=P, skin=0.0, x_list=None, density_in_build=False):
    """The production path: a pair list built (with ``skin``) at ``x_list`` (default ``x``),
    then the forces and densities at ``x``; with ``density_in_build`` the densities come
    from the list building (at ``x_list``) and only the near pairs are stored."""
    x_list = x if x_list is None else x_list
    n = len(x)
    rc_list = rc_f + skin if density_in_build else max(rc_f, rc_d) + skin
    cell = max(rc_list, rc_d)
    lo = np.minimum(x.min(axis=0), x_list.min(axis=0)) - cell
    hi = np.maximum(x.max(axis=0), x_list.max(axis=0)) + cell
    nx = int((hi[0] - lo[0]) / cell) + 1
    ny = int((hi[1] - lo[1]) / cell) + 1
    start = np.zeros(nx * ny + 1, np.int64)
    order = np.zeros(n, np.int64)
    K.build_cells(x_list, n, lo[0], lo[1], 1.0 / cell, nx, ny, start, order)
    pi = np.empty(n * n, np.int64)
    pj = np.empty(n * n, np.int64)
    rho = np.zeros(n)
    n_near, n_far = K.build_pairs(x_list, n, start, order, nx, ny, rc_list, rc_f + skin, pi, pj,
                                  rho, rc_d, p.R, density_in_build)
    assert n_near > 0 and (n_far == 0) == density_in_build
    F = np.zeros((n, 2))
    rad = np.full(n, p.r)
    K.pair_accel_list(x, v, n, pi, pj, n_near, n_far, rc_f, rc_d, rad, p.A, p.B, p.k,
                      p.kappa, p.m, p.R, F, rho, not density_in_build, rad, 1.0,
                      np.zeros((n, 2)))
    return F, rho


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("skin", [0.0, 0.2])
@pytest.mark.parametrize("density_in_build", [False, True])
def test_pair_forces_match_direct_formula(seed, skin, density_in_build):
    rng = np.random.default_rng(seed)
    n = 300
    x = rng.uniform(0, 8, (n, 2))  # about 4.7 ped/m^2: many bodies in contact
    v = rng.normal(0, 1, (n, 2))
    # with a skin the list is built where everyone was before moving up to skin/2
    step = rng.normal(0, 1, (n, 2))
    step *= 0.4999 * skin / np.maximum(np.hypot(step[:, 0], step[:, 1]), 1e-12)[:, None]
    F, rho = kernel_pairs(x, v, 1.2, 2.1, skin=skin, x_list=x - step,
                          density_in_build=density_in_build)
    Fd, rhod = direct_pairs(x, v, 1.2, 2.1)
    assert np.abs(F - Fd).max() <= 1e-12 * np.abs(Fd).max()
    if density_in_build:  # the densities where the list was built
        _, rhod = direct_pairs(x - step, v, 1.2, 2.1)
    np.testing.assert_allclose(rho, rhod, rtol=1e-13)
    # Newton's third law: the pair forces sum to zero to round-off
    assert np.abs(F.sum(axis=0)).max() <= 1e-12 * np.abs(F).sum()


def test_truncated_pair_force_is_negligible():
    f_cut = P.A * math.exp((2 * P.r - 1.2) / P.B)
    assert f_cut < 0.03  # N, against a driving force m U_f / tau = 124 N
    assert f_cut / (P.m * P.U_f / P.tau) < 3e-4


# ------------------------------------------------------------------ walls
def wall_pieces(room):
    """Maximal straight wall pieces of the room's rings, cut at exits: (a, b) pairs with
    the walkable area on the left, grouped per ring, and the corner types."""
    pieces = []
    for ring in room.boundary_rings:
        pts = np.asarray(ring.points)
        ccw = shapely.LinearRing(pts).is_ccw
        if (ring.owner < 0) != ccw:  # outline counter-clockwise, holes clockwise
            pts = pts[::-1]
        n = len(pts)
        segs = []
        for i in range(n):
            a, b = pts[i], pts[(i + 1) % n]
            mid = shapely.Point(0.5 * (a + b))
            is_exit = any(shapely.LineString(room.exit_polyline(k)).distance(mid) < 1e-9
                          for k in ring.exits)
            segs.append((a, b, is_exit))
        pieces.append(segs)
    return pieces


def direct_walls(x, v, room, rc_w, p=P):
    """Wall accelerations from the room's polygon walls (not the mesh): interior contacts
    of every straight piece, and each corner at most once (not when a piece meeting there
    has an interior contact)."""
    F = np.zeros((len(x), 2))
    for i, xi in enumerate(x):
        contacts = []
        for segs in wall_pieces(room):
            n = len(segs)
            ts = []
            for a, b, ex in segs:
                d = b - a
                ts.append(np.dot(xi - a, d) / np.dot(d, d))
            for s, (a, b, ex) in enumerate(segs):
                if ex:
                    continue
                t = ts[s]
                if 0 < t < 1:
                    contacts.append(a + t * (b - a))
                elif t <= 0:  # corner at a, shared with the previous piece
                    pa, pb, pex = segs[s - 1]
                    tp = ts[s - 1]
                    if pex or not (0 < tp < 1):
                        contacts.append(a)
                else:  # corner at b: counted by the next piece unless that is an exit
                    na, nb, nex = segs[(s + 1) % n]
                    if nex:
                        contacts.append(b)
        for c in contacts:
            d = float(np.hypot(*(xi - c)))
            if d >= rc_w or d == 0:
                continue
            nw = (xi - c) / d
            tw = np.array([-nw[1], nw[0]])
            g = max(p.r - d, 0.0)
            f = ((p.A * math.exp((p.r - d) / p.B) + p.k * g) * nw
                 - p.kappa * g * np.dot(v[i], tw) * tw)
            F[i] += f / p.m
    return F


@pytest.mark.parametrize("seed", [0, 1])
def test_wall_forces_match_direct_formula(seed):
    room = Room(
        [(0, 0), (12, 0), (12, 4), (6, 4), (6, 10), (0, 10)],
        obstacles=[Obstacle("pillar", [(2, 5), (3.5, 5), (3.5, 6.5), (2, 6.5)])],
        exits=[Exit("door", [(12, 1), (12, 3)]), Exit("top", [(2, 10), (4, 10)])],
    )
    mesh = triangulate(room, max_area=0.3)
    rc_w = 1.05
    walls = WallSet.from_mesh(mesh, rc_w)
    rng = np.random.default_rng(seed)
    # points near walls, corners (convex and reflex), door jambs, and anywhere
    corners = np.array([[0, 0], [12, 0], [6, 4], [2, 5], [3.5, 6.5], [12, 1], [12, 3], [2, 10],
                        [6, 10]], float)
    near = corners[rng.integers(0, len(corners), 600)] + rng.normal(0, 0.4, (600, 2))
    anywhere = rng.uniform([0, 0], [12, 10], (400, 2))
    x = np.concatenate([near, anywhere])
    x = x[mesh.locate(x) >= 0]
    v = rng.normal(0, 1, x.shape)
    F = np.zeros_like(x)
    K.wall_accel(x, v, len(x), walls.piece, walls.next_seg, walls.x0,
                 walls.y0, walls.inv_cell, walls.nx, walls.ny, walls.cell_ptr, walls.cell_seg,
                 rc_w, np.full(len(x), P.r), P.A, P.B, P.k, P.kappa, P.m, F,
                 np.full(len(x), P.r))
    Fd = direct_walls(x, v, room, rc_w)
    assert np.abs(F - Fd).max() <= 1e-9 * max(np.abs(Fd).max(), 1.0)
    assert np.abs(Fd).max() > 100  # some pedestrians are pressed into a wall
    # a pedestrian in front of a straight wall split into many mesh edges feels one wall
    xs = np.column_stack([np.linspace(0.5, 11.5, 200), np.full(200, 0.1)])
    xs = xs[mesh.locate(xs) >= 0]
    Fs = np.zeros_like(xs)
    K.wall_accel(xs, np.zeros_like(xs), len(xs), walls.piece, walls.next_seg, walls.x0, walls.y0,
                 walls.inv_cell, walls.nx, walls.ny,
                 walls.cell_ptr, walls.cell_seg, rc_w, np.full(len(xs), P.r), P.A, P.B, P.k,
                 P.kappa, P.m, Fs, np.full(len(xs), P.r))
    one_wall = (P.A * math.exp((P.r - 0.1) / P.B) + P.k * (P.r - 0.1)) / P.m
    far = (xs[:, 0] > 1.2) & (xs[:, 0] < 10.8) & ~((xs[:, 0] > 0.8) & (xs[:, 0] < 4.7))
    np.testing.assert_allclose(Fs[far, 1], one_wall, rtol=1e-12)
    np.testing.assert_allclose(Fs[far, 0], 0.0, atol=1e-9)
