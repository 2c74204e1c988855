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


def test_a_box_swept_through_the_body_between_knots_is_reported(g1):
    """The box of case_lift_box sits clear of the robot at both knots of an interval and passes
    through the legs between them: penetration_between_knots sees it, the knot check does not."""
    from types import SimpleNamespace

    from lomanip_to.checks import penetration_between_knots, penetration_per_knot
    from lomanip_to.discretize import ProblemData

    prob = load_problem("case_lift_box", model=g1)
    data = ProblemData(prob, g1)
    res = solver.solve(load_problem("case_stand", model=g1), g1)
    res = copy.copy(res)
    K = len(res.t_knots)
    x = res.x_knots[0]
    box = np.tile(np.r_[x[0] - 0.6, x[1], 0.2, 0.0, 0.0, 0.0], (K, 1))
    box[K // 2:, 0] = x[0] + 0.6  # jumps from behind to in front of the robot in one interval
    res.object_pose_knots = {"box": box}
    res.object_vel_knots = {"box": np.zeros((K, 6))}
    res.object_ids = ["box"]
    assert penetration_per_knot(g1, data, SimpleNamespace(t_knots=res.t_knots, x_knots=res.x_knots,
                                                          object_pose_knots={"box": box}))[1] < 1e-9
    depth, t = penetration_between_knots(g1, data, res)
    assert depth > 0.05
    assert res.t_knots[K // 2 - 1] < t < res.t_knots[K // 2]
