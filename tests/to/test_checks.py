"""lomanip_to.checks.foot_slip: a foot that carries force over an interval must not move over it."""

from types import SimpleNamespace

import numpy as np
import pytest

from lomanip_to.checks import foot_slip


def _result(left_points, left_objects):
    n = len(left_points)
    return SimpleNamespace(
        t_knots=np.arange(n) * 0.1,
        points_knots={"left_foot": np.asarray(left_points, float), "right_foot": np.zeros((n, 3))},
        contact_objects_knots={"left_foot": left_objects, "right_foot": ["floor"] * n},
    )


def test_planted_stance_and_free_swing_pass():
    res = _result([[0, 0, 0], [0, 0, 0], [0, 0, 0], [0.1, 0, 0.05], [0.2, 0, 0]], ["floor", "floor", "", "", "floor"])
    assert foot_slip(res)[0] == pytest.approx(0.0)


def test_lift_off_knot_that_already_moved_is_caught():
    # knot 1 is the last contact knot; its force acts until knot 2, where the sole is 15 cm ahead
    res = _result([[0, 0, 0], [0, 0, 0], [0.15, 0, 0.04], [0.2, 0, 0.05], [0.3, 0, 0]], ["floor", "floor", "", "", "floor"])
    value, (foot, t) = foot_slip(res)
    assert value == pytest.approx(np.hypot(0.15, 0.04))
    assert foot == "left_foot" and t == pytest.approx(0.1)
