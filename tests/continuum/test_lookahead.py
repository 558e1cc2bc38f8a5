"""eos's ``lookahead``: the speed law read at the density ahead, the crowd's density
averaged with the social force model's kernel and density cone about the desired direction
(pedmesh.models.continuum.lookahead)."""

from __future__ import annotations

import numpy as np
import pytest

from pedmesh import Exit, Room
from pedmesh.errors import ParameterError
from pedmesh.mesh import triangulate
from pedmesh.models.continuum import macro_model
from pedmesh.models.continuum.lookahead import Lookahead
from pedmesh.presets import preset_overrides
from pedmesh.models import get_model

R = 0.7


def _mesh(max_area=0.05):
    room = Room([(0, 0), (12, 0), (12, 6), (0, 6)], exits=[Exit("e", [(12, 2), (12, 4)])])
    return triangulate(room, max_area=max_area, feature_area=None)


def test_a_uniform_crowd_reads_its_density_whatever_the_cone():
    """Normalised by the weights inside the room: a uniform crowd reads its density
    everywhere, at walls and corners too (walls are mirrors), for any cone and direction."""
    mesh = _mesh(0.2)
    rho = np.full(mesh.n_triangles, 2.5)
    rng = np.random.default_rng(1)
    th = rng.uniform(0, 2 * np.pi, mesh.n_triangles)
    for p in (0.0, 1.0, 2.0, 4.0):
        ahead = Lookahead(mesh, R, p)(rho, np.cos(th), np.sin(th))
        np.testing.assert_allclose(ahead, 2.5, rtol=1e-12)


@pytest.mark.parametrize("p", [1.0, 2.0])
def test_the_cone_reads_the_crowd_ahead(p):
    """A density ramp rho = 1 + 0.2 x [ped/m^2] along x. Far from walls the isotropic average
    is the local density (a linear field, a symmetric kernel); people heading +x read more,
    people heading -x as much less: the cone's first moment, norm_p/(2 pi) int cos^(p+1)
    R/sqrt(pi)... measured against the continuous integral."""
    mesh = _mesh(0.01)
    c = mesh.centroids
    rho = 1.0 + 0.2 * c[:, 0]
    inner = (c[:, 0] > 3.5) & (c[:, 0] < 8.5) & (c[:, 1] > 2.5) & (c[:, 1] < 3.5)
    one = np.ones(mesh.n_triangles)
    zero = np.zeros(mesh.n_triangles)
    iso = Lookahead(mesh, R, 0.0)(rho, one, zero)[inner].copy()
    np.testing.assert_allclose(iso, rho[inner], atol=0.01)
    la = Lookahead(mesh, R, p)
    fwd = la(rho, one, zero)[inner].copy()
    back = la(rho, -one, zero)[inner].copy()
    # the continuous kernel's mean offset ahead: int_0^inf r^2 e^{-r^2/R^2} dr /
    # int_0^inf r e^{-r^2/R^2} dr * mean of norm_p cos^(p+1) over the half circle
    from scipy.integrate import quad
    from pedmesh.speed import cone_norm

    radial = (np.sqrt(np.pi) * R ** 3 / 4) / (R ** 2 / 2)
    ang = quad(lambda t: np.cos(t) ** (p + 1), -np.pi / 2, np.pi / 2)[0] / (2 * np.pi)
    shift = cone_norm(p) * ang * radial
    np.testing.assert_allclose(fwd - rho[inner], 0.2 * shift, rtol=0.03)
    np.testing.assert_allclose(back - rho[inner], -0.2 * shift, rtol=0.03)


def test_pieces_do_not_read_each_other():
    """A building's pieces lie side by side in one plane: a cell reads only its own piece."""
    from types import SimpleNamespace

    m = _mesh(0.5)
    piece = (m.centroids[:, 0] > 6.0).astype(int)
    mesh = SimpleNamespace(centroids=m.centroids, areas=m.areas, piece=piece,
                           n_triangles=m.n_triangles)
    rho = np.where(piece == 1, 4.0, 1.0)
    ahead = Lookahead(mesh, R, 2.0)(rho, np.ones(mesh.n_triangles),
                                    np.zeros(mesh.n_triangles))
    np.testing.assert_allclose(ahead, rho)


def test_eos_reads_ahead_only_with_its_kernel():
    """An option, not in the validated preset (measured against the social force model in
    docs/validation/dense_crowds.md: closer on Example 2 and the venue, far off at the
    corridor bottleneck); without exit_kernel it is refused with a message naming it."""
    ov = preset_overrides("validated", get_model("eos").parameter_names, continuum=True)
    assert "lookahead" not in ov and ov["exit_kernel"] > 0
    m = macro_model("eos", lookahead=2.0, exit_kernel=0.7)
    assert m.parameters()["lookahead"] == 2.0
    with pytest.raises(ParameterError, match="exit_kernel"):
        macro_model("eos", lookahead=2.0, exit_kernel=0.0)
