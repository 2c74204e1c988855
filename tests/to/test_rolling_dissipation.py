"""Rolling resistance dissipates: the wheels may brake the trolley, never drive it."""
import casadi as ca
import numpy as np
import pytest

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem
from lomanip_to.model import rpy_to_rot

ROW = "rolling: resistance opposes motion"


@pytest.fixture(scope="module")
def s2(g1):
    data = ProblemData(load_problem("s2_trolley", model=g1), g1)
    win, _ = solver.get_window(g1, data.structure)
    lbw, ubw, lbg, ubg, Pm, W0 = data.fill(win, *solver.homotopy_stages(data.prob.options)[-1])
    return data, win, lbg, ubg, Pm, W0


def test_the_row_is_on_only_while_the_object_rolls(s2):
    data, win, lbg, ubg, _, _ = s2
    j = data.midx["trolley"]
    rows = win.G[f"o{j} {ROW}"]
    rolling = [k for k in range(data.grid.K) if data.obj_mode(k, "trolley") == "rolling"]
    assert rolling and len(rolling) < data.grid.K
    for k in range(data.grid.K):
        assert np.all(ubg[rows, k] == (0.0 if k in rolling else np.inf))
        assert np.all(lbg[rows, k] == -np.inf)


def test_a_wheel_force_along_the_motion_violates_it_and_braking_does_not(s2):
    data, win, lbg, ubg, Pm, W0 = s2
    j = data.midx["trolley"]
    k = next(k for k in range(data.grid.K - 1) if data.obj_mode(k, "trolley") == "rolling")
    fg = ca.Function("g", [win.a, win.b, win.p], [win.g])
    a, b = W0[:, k].copy(), W0[:, k + 1].copy()
    heading = rpy_to_rot(a[win.W[f"o{j}_pose"]][3:6])[:, 0]
    heading = np.asarray(heading, float).ravel()
    b[win.W[f"o{j}_vel"]] = np.concatenate([0.3 * heading, np.zeros(3)])   # rolling forward
    rows = win.G[f"o{j} {ROW}"]
    for sign, violated in ((+1.0, True), (-1.0, False)):
        us = np.zeros((3, 4))
        us[:, 0] = sign * 0.004 * heading            # ~1.4 N on one wheel, along or against the motion
        us[2, :] += 0.05
        a[win.W[f"o{j}_us"]] = us.ravel(order="F")
        g = np.asarray(fg(a, b, Pm[:, k])).ravel()[rows]
        assert (g[0] > ubg[rows, k][0]) == violated, g
        np.testing.assert_allclose(g[1:], 0.0, atol=1e-12)   # the other wheels carry no longitudinal force
