"""eos's ``exit_kernel``: near an exit the speed law is read at the density the social
force model's kernel sees there (pedmesh.models.continuum.exit_kernel)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import erfc

from pedmesh import Exit, Room
from pedmesh.models.continuum import macro_model
from pedmesh.models.continuum.exit_kernel import exit_kernel_mass, interior_points
from pedmesh.models.continuum.solver import FVOptions, FVSolver
from pedmesh.mesh import triangulate
from pedmesh.presets import preset_overrides
from pedmesh.models import get_model


def _room(exit_lo=2.0, exit_hi=8.0):
    return Room([(0, 0), (10, 0), (10, 10), (0, 10)],
                exits=[Exit("e", [(10, exit_lo), (10, exit_hi)])])


def test_kernel_mass_beyond_a_straight_exit():
    """Half the kernel lies beyond the exit on its line, 0.5 erfc(s/R) at a distance s in
    front of a long exit's middle, nothing in front of a wall or far from the exit."""
    mesh = triangulate(_room(0.0, 10.0), max_area=0.5)
    R = 0.7
    s = np.array([0.0, 0.2, 0.5, 1.0, 2.0, 4.0])
    pts = np.c_[10.0 - s, np.full(len(s), 5.0)]
    cells = np.zeros(len(s), int)
    w = exit_kernel_mass(mesh, pts, cells, R)
    np.testing.assert_allclose(w, 0.5 * erfc(s / R), rtol=1e-6, atol=1e-9)
    assert w[0] == pytest.approx(0.5) and w[-1] < 1e-8
    # the exit 2..8 m: beside it, in front of the wall, the kernel sees far less of it
    mesh = triangulate(_room(), max_area=0.5)
    w_mid, w_side, w_wall = exit_kernel_mass(
        mesh, np.array([[9.7, 5.0], [9.7, 2.0], [9.7, 0.5]]), np.zeros(3, int), R)
    assert w_mid == pytest.approx(0.5 * erfc(0.3 / R), rel=1e-6)
    assert w_side == pytest.approx(0.5 * w_mid, rel=1e-6)  # (at the exit's end)
    assert w_wall < 1e-3
    assert not exit_kernel_mass(mesh, np.array([[9.7, 5.0]]), np.zeros(1, int), 0.0).any()


def test_eos_without_exit_kernel_is_the_local_law():
    """exit_kernel = 0 (every preset but validated): no factor, the barotropic relaxation."""
    mesh = triangulate(_room(), max_area=0.5)
    model = macro_model("eos")
    assert model.exit_kernel == 0.0
    FVSolver(mesh, model, FVOptions())
    assert model.seen is None


def test_exit_kernel_raises_the_desired_speed_in_front_of_the_exit():
    """With exit_kernel the relaxation towards the exit is stronger right in front of it
    (a lower density read), the same far from it; one pass and the generic path agree."""
    mesh = triangulate(_room(), max_area=0.2)
    table = get_model("eos").parameter_names
    law = {k: v for k, v in preset_overrides("validated", table, continuum=True).items()
           if k in ("speed_law", "speed_table", "U_f", "tau")}
    base, seen = macro_model("eos", **law), macro_model("eos", exit_kernel=0.7, **law)
    sb, ss = FVSolver(mesh, base, FVOptions()), FVSolver(mesh, seen, FVOptions())
    assert seen.seen is not None and seen.seen.shape == (mesh.n_triangles, 3)
    assert seen.seen.min() == pytest.approx(0.5, abs=0.1) and seen.seen.max() == 1.0
    Q = base.initial_state(np.full(mesh.n_triangles, 5.0))
    for s in (sb, ss):
        s.update_route(Q)
    d_base, _ = sb.residual(Q, 0.0, 1e-4)
    d_seen, _ = ss.residual(Q, 0.0, 1e-4)
    c = interior_points(mesh).mean(axis=1)
    front = (c[:, 0] > 9.5) & (np.abs(c[:, 1] - 5.0) < 2.0)
    far = c[:, 0] < 7.0
    assert np.all(d_seen[front, 1] > d_base[front, 1] + 0.05)
    np.testing.assert_array_equal(d_seen[far], d_base[far])
    seen.source_mean = None  # the generic path: point sources, then the mean
    d_gen, _ = ss.residual(Q, 0.0, 1e-4)
    np.testing.assert_allclose(d_gen, d_seen, rtol=0, atol=1e-13 * np.abs(d_seen).max())


def test_only_the_validated_preset_sets_it():
    names = get_model("eos").parameter_names
    assert "exit_kernel" in names
    assert preset_overrides("validated", names, continuum=True)["exit_kernel"] == 0.7
    for pre in ("paper", "weidmann"):
        assert "exit_kernel" not in preset_overrides(pre, names, continuum=True)
    for model in ("rdue", "pw", "sfm"):
        assert "exit_kernel" not in get_model(model).parameter_names


def test_the_cone_sees_through_the_exit():
    """With the social force model's density cone the mass beyond an exit is what people
    heading out see: all of it on the exit line (1, the isotropic kernel's 1/2), and the
    quadrature against a direct integration over the plane."""
    import math

    from pedmesh.models.continuum.exit_kernel import cone_mass_beyond

    R = 0.7
    assert cone_mass_beyond(np.array([0.0]), R, 2.0)[0] == pytest.approx(1.0, rel=1e-9)
    # direct: a fine polar grid of the cone-weighted kernel beyond y = s
    r = np.linspace(1e-4, 6 * R, 3000)
    th = np.linspace(-math.pi / 2, math.pi / 2, 2001)
    Rr, T = np.meshgrid(r, th, indexing="ij")
    dens = np.exp(-(Rr / R) ** 2) / (math.pi * R * R) * 4.0 * np.cos(T) ** 2 * Rr
    for s in (0.2, 0.5, 1.0):
        beyond = Rr * np.cos(T) > s
        direct = np.trapezoid(np.trapezoid(dens * beyond, th, axis=1), r)
        assert cone_mass_beyond(np.array([s]), R, 2.0)[0] == pytest.approx(direct, rel=2e-3)
