"""lomanip_to.checks.torque_ratio_between_knots: joint torques of the motion a controller tracks."""
import copy

import pytest

from lomanip_to import solver
from lomanip_to.checks import torque_ratio, torque_ratio_between_knots
from lomanip_to.fixtures import load_problem


@pytest.fixture(scope="module")
def stand(g1):
    return solver.solve(load_problem("case_stand", model=g1), g1)


def test_a_converged_stand_needs_between_knots_what_it_needs_at_them(g1, stand):
    value, (joint, t) = torque_ratio_between_knots(g1, stand)
    at_knots = torque_ratio(g1, stand)[0]
    assert 0.0 < value < 1.0 and abs(value - at_knots) < 0.05, (value, at_knots, joint, t)
    entry = stand.stats.checks["torque_limits"]
    assert entry["between_knots"] == pytest.approx(value) and joint in entry["between_knots_where"]


def test_arms_swung_between_knots_need_torque_the_knots_never_see(g1, stand):
    """Both shoulders pitch 1.6 rad forward and back over two knot intervals with the knot
    velocities left at zero: the knot check sees a still robot, the interpolant whips the arms."""
    res = copy.copy(stand)
    res.x_knots = stand.x_knots.copy()
    k = len(res.t_knots) // 2
    for name in ("left_shoulder_pitch_joint", "right_shoulder_pitch_joint"):
        res.x_knots[k, 6 + g1.joint_names.index(name)] -= 1.6
    assert torque_ratio(g1, res)[0] < 1.0
    value, (joint, t) = torque_ratio_between_knots(g1, res)
    assert value > 1.0 and "shoulder" in joint
    assert res.t_knots[k - 1] <= t <= res.t_knots[k + 1]
