"""pedmesh.mesh.distance: the compiled nearest-segment distance the meshers' size fields
read is the distance GEOS computes, to the bit (so the meshes graded by it are those of
an STR tree's nearest search), with and without its grid, for points far outside the
segments' box, on ties and for segments of length zero."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from pedmesh.mesh.distance import BRUTE_MAX, SegmentDistance

from geos_reference import geos_distance as _geos  # (tests/geos_reference.py)


@pytest.mark.parametrize("n", [1, 7, BRUTE_MAX + 1, 400, 3000])
def test_the_distance_is_geos_to_the_bit(n):
    rng = np.random.default_rng(n)
    seg = rng.uniform(0.0, 30.0, (n, 2, 2))
    # short pieces (a wall cut up), some points (corners), and a few long ones
    seg[:, 1] = seg[:, 0] + rng.uniform(-0.4, 0.4, (n, 2))
    seg[: n // 4, 1] = seg[: n // 4, 0]
    seg[n - n // 10:, 1] = rng.uniform(0.0, 30.0, (n // 10, 2))
    pts = np.concatenate([rng.uniform(-40.0, 70.0, (20_000, 2)),  # inside and far out
                          seg[:, 0], seg[:, 1], 0.5 * (seg[:, 0] + seg[:, 1]),
                          np.round(rng.uniform(0.0, 30.0, (5_000, 2)), 1)])
    d = SegmentDistance(seg)(pts)
    nx, ny = SegmentDistance(seg).grid[3:5]
    assert (nx * ny == 1) == (n <= BRUTE_MAX)  # (all segments in one cell: brute force)
    np.testing.assert_array_equal(d, _geos(seg, pts))


def test_axis_aligned_walls_and_grid_points():
    """A room's walls on a grid of points, many on the walls' lines and at equal distance
    from two walls (ties)."""
    ring = np.array([[0, 0], [10, 0], [10, 6], [4, 6], [4, 3], [0, 3], [0, 0]], float)
    line = shapely.segmentize(shapely.LineString(ring), 0.25)
    c = np.asarray(line.coords)
    seg = np.stack([c[:-1], c[1:]], axis=1)
    g = np.arange(-2.0, 12.01, 0.125)
    pts = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    assert len(seg) > BRUTE_MAX
    np.testing.assert_array_equal(SegmentDistance(seg)(pts), _geos(seg, pts))


def test_no_segments_is_infinitely_far():
    d = SegmentDistance(np.zeros((0, 2, 2)))(np.zeros((3, 2)))
    assert d.shape == (3,) and np.all(np.isinf(d))
    assert len(SegmentDistance(np.zeros((0, 2, 2)))) == 0
