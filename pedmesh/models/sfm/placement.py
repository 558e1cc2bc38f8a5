"""Seeded start positions: the start areas' lattice, each point moved at random.

``Room.initial_positions()`` places the crowd on a regular lattice, the paper's set-up and
the same every time. An ensemble needs members that differ: :func:`seeded_positions`
moves every lattice point by a uniform random offset in [-a, a]^2, with ``a`` chosen so
that two moved points stay at least a body diameter (plus a margin) apart, and keeps a
point where it was if its move would take it within a body radius of a wall. The count,
the areas and the mean density stay those of the lattice; the seed makes it repeatable.
"""

from __future__ import annotations

import numpy as np

from ...parameters import DEFAULTS as D

__all__ = ["seeded_positions"]


def seeded_positions(room, seed: int, *, radius: float = D['r'],
                     margin: float = 0.02) -> np.ndarray:
    """Start positions (N, 2) [m] of ``room``'s start areas, jittered with ``seed``.

    ``radius`` [m] is the body radius and ``margin`` [m] the extra gap kept between bodies
    and between a body and a wall. Same seed, same positions; the order is that of
    ``room.initial_positions()``.
    """
    import shapely
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(seed)
    inner = room.walkable.buffer(-(radius + margin))
    parts = []
    for area in room.start_areas:
        base = area.positions(room.walkable)
        if len(base) < 2 or area.arrivals is not None:  # (an entrance: placeholders)
            parts.append(base)
            continue
        spacing = float(cKDTree(base).query(base, k=2)[0][:, 1].min())
        a = max(0.0, 0.5 * (spacing - 2.0 * radius - margin))
        moved = base + rng.uniform(-a, a, base.shape)
        ok = shapely.contains_xy(inner, moved[:, 0], moved[:, 1])
        parts.append(np.where(ok[:, None], moved, base))
    if not parts:
        return np.zeros((0, 2))
    base = room.initial_positions()
    pos = np.concatenate(parts, axis=0)
    # start areas next to each other: undo the moves that bring two bodies too close
    tree = cKDTree(pos)
    for i, j in tree.query_pairs(2.0 * radius + margin):
        if np.hypot(*(base[i] - base[j])) > np.hypot(*(pos[i] - pos[j])):
            pos[i], pos[j] = base[i], base[j]
    return pos
