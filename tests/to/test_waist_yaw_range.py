"""Options.waist_yaw_range: a posture range for the waist yaw in the TO's bounds and its warm start."""
import numpy as np

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem


def test_off_by_default_keeps_the_g1_limit(g1):
    j = g1.joint_names.index("waist_yaw_joint")
    lo, hi = g1.gait_q_bounds()
    assert lo[j] == g1.q_lower[j] and hi[j] == g1.q_upper[j]


def test_range_narrows_the_waist_yaw_only(g1):
    j = g1.joint_names.index("waist_yaw_joint")
    lo0, hi0 = g1.gait_q_bounds()
    lo, hi = g1.gait_q_bounds(0.8)
    assert (lo[j], hi[j]) == (-0.8, 0.8)
    others = np.arange(len(lo)) != j
    np.testing.assert_array_equal(lo[others], lo0[others])
    np.testing.assert_array_equal(hi[others], hi0[others])


def test_a_start_outside_the_range_stays_feasible(g1):
    j = g1.joint_names.index("waist_yaw_joint")
    q0 = np.zeros(len(g1.joint_names))
    q0[j] = -1.1
    lo, hi = g1.gait_q_bounds(0.8, q0)
    assert lo[j] == -1.1 and hi[j] == 0.8


def test_the_nlp_bounds_hold_the_range_at_every_knot(g1):
    prob = load_problem("case_one_step", model=g1)
    prob.options = prob.options.replaced(waist_yaw_range=0.5)
    data = ProblemData(prob, g1)
    win, _ = solver.get_window(g1, data.structure)
    lbw, ubw = data.fill(win, 2.0, True, True, True)[:2]
    j = 6 + g1.joint_names.index("waist_yaw_joint")
    xs = win.W["x"]
    for k in range(1, data.grid.K):  # knot 0 is pinned to the measured start
        assert lbw[xs, k][j] == -0.5 and ubw[xs, k][j] == 0.5
