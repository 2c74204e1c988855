"""The TO's gait rows: hip yaw within its gait range and the soles on their own side of the pelvis."""
import casadi as ca
import numpy as np

from lomanip_to import solver
from lomanip_to.discretize import FEET_MIN_LATERAL, ProblemData
from lomanip_to.fixtures import load_problem
from lomanip_to.model import HIP_YAW_GAIT_RANGE


def _filled(g1):
    data = ProblemData(load_problem("case_one_step", model=g1), g1)
    win, _ = solver.get_window(g1, data.structure)
    return data, win, data.fill(win, 2.0, True, True, True)


def test_hip_yaw_bounds_and_feet_apart_row_bounds(g1):
    data, win, (lbw, ubw, lbg, ubg, _, _) = _filled(g1)
    xs = win.W["x"]
    for j in g1.hip_yaw_indices:
        assert lbw[xs, 1][6 + j] == -HIP_YAW_GAIT_RANGE and ubw[xs, 1][6 + j] == HIP_YAW_GAIT_RANGE
        assert g1.q_upper[j] > HIP_YAW_GAIT_RANGE  # narrower than the G1's own limit
    row = win.G["feet apart"]
    assert lbg[row, 0] == -np.inf  # knot 0 is the measured start, whatever it is
    assert np.all(lbg[row, 1:] == FEET_MIN_LATERAL)


def test_feet_apart_row_is_negative_for_crossed_legs(g1):
    data, win, (_, _, _, _, Pm, W0) = _filled(g1)
    g = ca.Function("g", [win.a, win.b, win.p], [win.g])
    row = win.G["feet apart"]
    a = W0[:, 1].copy()
    stand = float(np.array(g(a, W0[:, 2], Pm[:, 1])).ravel()[row][0])
    assert 0.2 < stand < 0.3  # the G1 stands with its soles about 0.24 m apart
    xs = win.W["x"]
    names = list(g1.pin_model.names[2:])
    x = a[xs].copy()
    x[6 + names.index("left_hip_roll_joint")] = -0.5  # both legs adducted: the ankles cross
    x[6 + names.index("right_hip_roll_joint")] = 0.5
    a[xs] = x
    crossed = float(np.array(g(a, W0[:, 2], Pm[:, 1])).ravel()[row][0])
    assert crossed < 0.0
