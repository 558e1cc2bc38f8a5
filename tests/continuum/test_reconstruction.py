"""CWENO3 reconstruction on triangles: conservation, exactness and third order."""

from __future__ import annotations

import numpy as np
import pytest

from pedmesh import Exit, Room
from pedmesh.models.continuum.quadrature import cell_averages
from pedmesh.models.continuum.reconstruction import INTERIOR_BARY, build_reconstruction
from pedmesh.mesh import triangulate

ROOM = Room([(0, 0), (4, 0), (4, 3), (0, 3)], exits=[Exit("e", [(4, 1), (4, 2)])])


def _points(mesh, R):
    P = mesh.points[mesh.triangles]
    pts = np.zeros((mesh.n_triangles, 9, 2))
    pts[:, :6] = R.edge_pt[mesh.triangle_edges].reshape(-1, 6, 2)
    pts[:, 6:] = np.einsum("pb,mbd->mpd", INTERIOR_BARY, P)
    return pts


def _recon(mesh, q, order=3, eps_hat=0.1):
    R = build_reconstruction(mesh)
    ve = np.zeros((mesh.n_triangles, 6, q.shape[1]))
    vi = np.zeros((mesh.n_triangles, 3, q.shape[1]))
    R.apply(q, ve, vi, order=order, eps_hat=eps_hat)
    return R, np.concatenate([ve, vi], axis=1)


def test_cell_averages_are_kept():
    mesh = triangulate(ROOM, max_area=0.01)
    rng = np.random.default_rng(0)
    q = rng.random((mesh.n_triangles, 3))  # rough data: all weights nonlinear
    _, V = _recon(mesh, q)
    # the 3 interior points are exact for quadratics: their mean is the cell average
    np.testing.assert_allclose(V[:, 6:].mean(axis=1), q, rtol=0, atol=1e-13)


def test_quadratics_are_exact_with_linear_weights():
    mesh = triangulate(ROOM, max_area=0.01)

    def f(x, y):
        return 1.0 + 0.3 * x - 0.7 * y + 0.2 * x * x - 0.1 * x * y + 0.4 * y * y

    q = cell_averages(mesh, f)[:, None]
    R, V = _recon(mesh, q, eps_hat=1e8)  # huge eps: linear weights, P = P_opt
    pts = _points(mesh, R)
    quad = R.opt_degree == 2
    assert quad.mean() > 0.95
    np.testing.assert_allclose(V[quad, :, 0], f(pts[quad, :, 0], pts[quad, :, 1]), atol=1e-11)


def test_third_order_for_smooth_data():
    def f(x, y):
        return np.sin(1.3 * x) * np.cos(0.9 * y) + 0.3 * x * y

    errs, hs = [], []
    for a in (0.02, 0.005, 0.00125):
        mesh = triangulate(ROOM, max_area=a)
        q = cell_averages(mesh, f)[:, None]
        R, V = _recon(mesh, q)
        pts = _points(mesh, R)
        errs.append(np.abs(V[..., 0] - f(pts[..., 0], pts[..., 1])).mean())
        hs.append(mesh.h)
    order = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert order > 2.8, (errs, order)


def test_no_new_extrema_at_a_jump():
    mesh = triangulate(ROOM, max_area=0.005)
    x = mesh.centroids[:, 0]
    q = np.where(x < 2.0 + 0.3 * mesh.centroids[:, 1], 1.0, 0.0)[:, None]
    _, V = _recon(mesh, q)
    # CWENO keeps overshoots small (the positivity limiter removes the rest)
    assert V.max() < 1.1 and V.min() > -0.1


@pytest.mark.parametrize("order", [1, 2])
def test_lower_orders(order):
    mesh = triangulate(ROOM, max_area=0.01)
    q = cell_averages(mesh, lambda x, y: 2 * x + y)[:, None]
    R, V = _recon(mesh, q, order=order)
    if order == 1:
        np.testing.assert_array_equal(V[..., 0], np.repeat(q, 9, axis=1))
    else:
        pts = _points(mesh, R)
        ok = R.opt_degree >= 1
        np.testing.assert_allclose(V[ok, :, 0], 2 * pts[ok, :, 0] + pts[ok, :, 1], atol=1e-10)


@pytest.mark.parametrize("order", [3, 2, 1])
def test_three_variable_kernel_equals_the_general_one(order):
    """Three variables (density, momentum) take a kernel of their own; it must give the
    general kernel's values, on rough data, smooth data, jumps and empty regions alike."""
    from pedmesh.models.continuum.reconstruction import reconstruct

    mesh = triangulate(ROOM, max_area=0.01)
    R = build_reconstruction(mesh)
    c = mesh.centroids
    rng = np.random.default_rng(7)
    q = np.stack([1 + np.sin(2 * c[:, 0]), 0.3 * rng.random(len(c)),
                  np.where(c[:, 1] > 1.5, 1.0, -1.0)], 1)
    q[c[:, 0] > 3] = 0.0  # a flat empty part
    m = mesh.n_triangles
    ve = np.zeros((m, 6, 3))
    vi = np.zeros((m, 3, 3))
    R.apply(q, ve, vi, order=order, qref=np.array([1.0, 0.5, 2.0]))
    ge = np.zeros((6 * m, 3))
    gi = np.zeros((m, 3, 3))
    reconstruct(q, order, R.stencil, R.R, R.opt_degree, R.moments, R.pairs, R.pair_inv,
                R.n_pairs, R.h, 0.1, np.array([1.0, 0.5, 2.0]), R.point_xy, ge,
                np.arange(6 * m).reshape(m, 6), gi, np.ones(m, np.bool_))
    np.testing.assert_allclose(ve.reshape(-1, 3), ge, rtol=0, atol=1e-13)
    np.testing.assert_allclose(vi, gi, rtol=0, atol=1e-13)


def test_positivity_limiter_inside_the_three_variable_kernel():
    """The 3-variable kernel applies the Zhang-Shu limiter as it writes the points; it must
    give what the separate limiter pass gives after the unlimited reconstruction, with
    vacuum, near-vacuum (below rho_cut) and steep data where it acts."""
    from pedmesh.models.continuum.fv_kernels import positivity_limit

    mesh = triangulate(ROOM, max_area=0.01)
    R = build_reconstruction(mesh)
    c = mesh.centroids
    rng = np.random.default_rng(3)
    rho = np.where(rng.random(len(c)) < 0.3, 0.0, 3.0 * rng.random(len(c)) ** 3)
    rho[rng.random(len(c)) < 0.1] = 5e-4  # below rho_cut
    q = np.stack([rho, rho * rng.normal(size=len(c)), rho * rng.normal(size=len(c))], 1)
    m = mesh.n_triangles
    ve, vi = np.zeros((m, 6, 3)), np.zeros((m, 3, 3))
    R.apply(q, ve, vi, positivity=(0.0, 1e-3))
    ge, gi = np.zeros((m, 6, 3)), np.zeros((m, 3, 3))
    R.apply(q, ge, gi)
    acts = min(ge[..., 0].min(axis=1).min(), gi[..., 0].min())
    assert acts < -1e-3  # unlimited: negative densities
    positivity_limit(ge.reshape(-1, 3), np.arange(6 * m).reshape(m, 6), gi, q, 0.0, 1e-3,
                     np.ones(m, np.bool_))
    np.testing.assert_allclose(ve, ge, rtol=0, atol=1e-14)
    np.testing.assert_allclose(vi, gi, rtol=0, atol=1e-14)
    # non-negative up to the round-off of the scaling (both paths alike)
    assert ve[..., 0].min() > -1e-15 and vi[..., 0].min() > -1e-15


@pytest.mark.parametrize("order", [3, 2, 1])
@pytest.mark.parametrize("limit", [False, True])
def test_one_variable_kernel_equals_the_general_one(order, limit):
    """One variable (rdue's density) takes a kernel of its own; it must give the general
    kernel's values followed by the separate positivity limiter, on rough, smooth, steep,
    near-vacuum and empty data."""
    from pedmesh.models.continuum.fv_kernels import positivity_limit
    from pedmesh.models.continuum.reconstruction import reconstruct

    mesh = triangulate(ROOM, max_area=0.01)
    R = build_reconstruction(mesh)
    c = mesh.centroids
    rng = np.random.default_rng(3)
    q = (1 + np.sin(2 * c[:, 0]) + 2.0 * (c[:, 1] > 1.5) * rng.random(len(c)))[:, None]
    q[c[:, 0] > 3] = 0.0  # a flat empty part
    q[rng.random(len(c)) < 0.05] = 5e-4  # below rho_cut
    m = mesh.n_triangles
    ve, vi = np.zeros((m, 6, 1)), np.zeros((m, 3, 1))
    R.apply(q, ve, vi, order=order, positivity=(0.0, 1e-3) if limit else None)
    ge, gi = np.zeros((6 * m, 1)), np.zeros((m, 3, 1))
    slot, every = np.arange(6 * m).reshape(m, 6), np.ones(m, np.bool_)
    reconstruct(q, order, R.stencil, R.R, R.opt_degree, R.moments, R.pairs, R.pair_inv,
                R.n_pairs, R.h, 0.1, np.ones(1), R.point_xy, ge, slot, gi, every)
    if limit:
        positivity_limit(ge, slot, gi, q, 0.0, 1e-3, every)
    np.testing.assert_allclose(ve.reshape(-1, 1), ge, rtol=0, atol=1e-13)
    np.testing.assert_allclose(vi, gi, rtol=0, atol=1e-13)
