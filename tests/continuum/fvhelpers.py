from __future__ import annotations

import numpy as np

from pedmesh.models.continuum.quadrature import cell_averages
from pedmesh.models.continuum.solver import FVController, FVOptions, FVSolver, FVState


def no_route(x, y):
    """A fixed zero desired direction (models run without the eikonal)."""
    return np.zeros(np.shape(x) + (2,))


def run_to(mesh, model, init, t_end, *, boundary=None, options=None, direction=None,
           each_step=None):
    """Run a model from cell averages of ``init(x, y)`` to ``t_end``; returns the state."""
    s = FVSolver(mesh, model, options or FVOptions(), boundary_state=boundary,
                 direction=direction)
    st = FVState(cell_averages(mesh, init, subdivisions=2 if boundary is None else 3))
    if st.Q.ndim == 1:
        st.Q = st.Q[:, None]
    c = FVController(s, st)
    while st.t < t_end - 1e-12:
        c.advance(t_end)
        if each_step is not None:
            each_step(s, st)
    return s, st
