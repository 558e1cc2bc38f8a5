"""Accurate cell averages of functions on triangles (for initial data and exact solutions)."""

from __future__ import annotations

import numpy as np

__all__ = ["cell_averages", "DUNAVANT7"]

# Dunavant's degree-5 rule (7 points): barycentric coordinates and weights (sum 1)
_a1, _b1 = 0.059715871789770, 0.470142064105115
_a2, _b2 = 0.797426985353087, 0.101286507323456
DUNAVANT7 = (
    np.array([[1 / 3, 1 / 3, 1 / 3],
              [_a1, _b1, _b1], [_b1, _a1, _b1], [_b1, _b1, _a1],
              [_a2, _b2, _b2], [_b2, _a2, _b2], [_b2, _b2, _a2]]),
    np.array([0.225] + [0.132394152788506] * 3 + [0.125939180544827] * 3),
)


def cell_averages(mesh, fn, subdivisions: int = 2) -> np.ndarray:
    """Cell averages of ``fn(x, y) -> (p,) or (p, nv)`` over every triangle of ``mesh``.

    Each triangle is split into ``4**subdivisions`` similar triangles and integrated with
    the 7-point degree-5 rule (error O(h^6 / 4^(3 subdivisions)) for smooth fn).
    """
    bary, w = DUNAVANT7
    # barycentric sub-triangles of the reference triangle
    subs = [np.eye(3)]
    for _ in range(subdivisions):
        nxt = []
        for T in subs:
            a, b, c = T
            ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
            nxt += [np.array([a, ab, ca]), np.array([ab, b, bc]), np.array([ca, bc, c]),
                    np.array([ab, bc, ca])]
        subs = nxt
    lam = np.concatenate([bary @ T for T in subs])  # (q, 3) barycentric in the big triangle
    wt = np.tile(w, len(subs)) / len(subs)
    P = mesh.points[mesh.triangles]  # (m, 3, 2)
    xy = np.einsum("qb,mbd->mqd", lam, P)
    vals = np.asarray(fn(xy[..., 0].ravel(), xy[..., 1].ravel()))
    vals = vals.reshape(mesh.n_triangles, len(wt), *vals.shape[1:])
    return np.einsum("q,mq...->m...", wt, vals)
