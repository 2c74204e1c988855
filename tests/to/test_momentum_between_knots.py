"""lomanip_to.checks.momentum_between_knots: the densified motion must carry the plan's momentum."""
import copy

import numpy as np
import pytest

from lomanip_to import solver
from lomanip_to.checks import TOL, momentum_between_knots
from lomanip_to.fixtures import load_problem


@pytest.fixture(scope="module")
def stand(g1):
    return solver.solve(load_problem("case_stand", model=g1), g1)


def test_a_converged_stand_carries_its_momentum_between_knots(g1, stand):
    value, _ = momentum_between_knots(g1, stand)
    assert value < 0.1
    assert stand.stats.checks["momentum_between_knots"]["ok"]


def test_arms_swung_between_knots_are_caught(g1, stand):
    """Both shoulders pitch 1.6 rad forward and back over two knot intervals while the plan's
    momentum stays zero: the interpolant swings the arms the knots never see."""
    res = copy.copy(stand)
    res.x_knots = stand.x_knots.copy()
    k = len(res.t_knots) // 2
    for name in ("left_shoulder_pitch_joint", "right_shoulder_pitch_joint"):
        res.x_knots[k, 6 + g1.joint_names.index(name)] -= 1.6
    value, t = momentum_between_knots(g1, res)
    assert value > TOL["momentum_between_knots"]
    assert res.t_knots[k - 1] < t < res.t_knots[k + 1]
