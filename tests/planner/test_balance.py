"""Support polygon and margin of a keyframe's CoM (lomanip_planner.balance)."""
from __future__ import annotations

import numpy as np
import pytest

from lomanip_planner.balance import combined_com, convex_hull, support_margin

SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def test_hull_drops_interior_and_repeated_points_and_runs_counter_clockwise():
    points = np.concatenate([SQUARE, [[0.5, 0.5], [0.2, 0.7], [1.0, 1.0], [0.5, 0.0]]])
    hull = convex_hull(points)
    assert len(hull) == 4 and {tuple(p) for p in hull} == {tuple(p) for p in SQUARE}
    x, y = hull[:, 0], hull[:, 1]
    assert 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) == pytest.approx(1.0)   # positive area


@pytest.mark.parametrize("point, margin, normal", [((0.5, 0.5), 0.5, None), ((0.9, 0.5), 0.1, (1.0, 0.0)),
                                                   ((0.5, 1.3), -0.3, (0.0, 1.0)), ((-0.2, 0.4), -0.2, (-1.0, 0.0))])
def test_margin_is_the_signed_distance_to_the_nearest_or_most_violated_edge(point, margin, normal):
    m, n = support_margin(np.array([*point, 0.7]), convex_hull(SQUARE))
    assert m == pytest.approx(margin)
    if normal is not None:
        np.testing.assert_allclose(n, normal, atol=1e-12)


def test_moving_the_polygon_along_the_normal_raises_the_margin_by_the_move():
    hull = convex_hull(SQUARE)
    m, n = support_margin(np.array([1.25, 0.5]), hull)
    m2, _ = support_margin(np.array([1.25, 0.5]), hull + 0.3 * n)
    assert m2 == pytest.approx(m + 0.3)


def test_a_degenerate_polygon_is_refused():
    with pytest.raises(ValueError):
        support_margin(np.zeros(2), convex_hull(SQUARE[:2]))


def test_combined_com_weights_the_load_by_its_mass():
    np.testing.assert_allclose(combined_com(30.0, np.zeros(3), 10.0, np.array([0.4, 0.0, 1.0])), [0.1, 0.0, 0.25])
    np.testing.assert_allclose(combined_com(30.0, np.ones(3)), np.ones(3))
