"""Options.torque_margin: the fraction of each joint's torque limit the TO's torque rows allow."""
import numpy as np
import pytest

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem
from lomanip_to.problem import INVALID_REQUEST, ProblemError, validate_problem


def _torque_row_bounds(prob, g1):
    data = ProblemData(prob, g1)
    win, _ = solver.get_window(g1, data.structure)
    _, _, lbg, ubg, _, _ = data.fill(win, 2.0, True, True, True)
    rows = win.G["joint torques"]
    return lbg[rows], ubg[rows]


@pytest.mark.parametrize("margin", [0.8, 0.6])
def test_every_torque_row_is_bounded_by_the_margin(g1, margin):
    prob = load_problem("case_one_step", model=g1)
    prob.options = prob.options.replaced(torque_margin=margin)
    lo, hi = _torque_row_bounds(prob, g1)
    n = sum(len(js) for js, _ in g1.torque_row_joints.values())
    assert lo.shape[0] == n
    np.testing.assert_array_equal(hi, margin)
    np.testing.assert_array_equal(lo, -margin)


@pytest.mark.parametrize("bad", [0.0, -0.1, 1.2, float("nan")])
def test_a_margin_outside_0_1_is_refused_before_solving(g1, bad):
    prob = load_problem("case_one_step", model=g1)
    prob.options = prob.options.replaced(torque_margin=bad)
    with pytest.raises(ProblemError, match="torque_margin") as ei:
        validate_problem(prob, g1)
    assert ei.value.code == INVALID_REQUEST
