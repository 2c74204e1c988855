"""The carried-object pose cost (weight ``w_carry_pose``): level, and its yaw relative to the base."""
import dataclasses
import math

import casadi as ca
import numpy as np
import pytest

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem


@pytest.fixture(scope="module")
def s1(g1):
    prob = load_problem("s1_basket", model=g1)
    prob = dataclasses.replace(prob, options=prob.options.replaced(weights={"w_carry_pose": 50.0}))
    data = ProblemData(prob, g1)
    win, _ = solver.get_window(g1, data.structure)
    lbw, ubw, lbg, ubg, Pm, W0 = data.fill(win, *solver.homotopy_stages(prob.options)[-1])
    return data, win, Pm, W0


def test_weight_acts_on_carried_knots_only(s1):
    data, win, Pm, _ = s1
    j = data.midx["box"]
    w = Pm[win.P[f"o{j}_w_pose"]].ravel()
    rel = Pm[win.P[f"o{j}_yaw_rel"]].ravel()
    free = [k for k in range(data.grid.K) if data.obj_mode(k, "box") == "free"]
    assert free and all(w[k] == 50.0 for k in free)
    assert all(w[k] == 0.0 for k in range(data.grid.K) if k not in free)
    nominal = data.carry_yaw_rel["box"]
    for k in free:  # the nominal's yaw relative to the nominal base (the blend's, not the guess's)
        assert np.isfinite(nominal[k]) and rel[k] == pytest.approx(math.remainder(nominal[k], 2 * math.pi))


def test_cost_grows_with_tilt_and_relative_yaw(s1):
    data, win, Pm, W0 = s1
    j = data.midx["box"]
    k = next(k for k in range(data.grid.K - 1) if data.obj_mode(k, "box") == "free")
    f = ca.Function("f", [win.a, win.b, win.p], [win.f])
    a, b = W0[:, k].copy(), W0[:, k + 1].copy()
    pose = win.W[f"o{j}_pose"]
    yaw_base = a[win.W["x"]][5]
    rel = float(Pm[win.P[f"o{j}_yaw_rel"], k][0])
    p_on, p_off = Pm[:, k].copy(), Pm[:, k].copy()
    p_off[win.P[f"o{j}_w_pose"]] = 0.0
    w_stage = float(Pm[win.P["w_stage"], k][0])

    def extra(roll, pitch, dyaw):
        aa = a.copy()
        idx = np.arange(win.W.n)[pose]
        aa[idx[3:6]] = [roll, pitch, yaw_base + rel + dyaw]
        return float(f(aa, b, p_on)) - float(f(aa, b, p_off))

    assert extra(0.0, 0.0, 0.0) == pytest.approx(0.0, abs=1e-9)
    assert extra(0.0, 0.0, 0.5) == pytest.approx(w_stage * 50 * 2 * (1 - math.cos(0.5)), rel=1e-9)
    assert extra(0.1, -0.2, 0.0) == pytest.approx(w_stage * 50 * (0.01 + 0.04), rel=1e-9)
    # periodic in the yaw: a full turn costs nothing
    assert extra(0.0, 0.0, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
