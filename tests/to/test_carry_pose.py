"""The carried-object costs: ``w_carry_pose`` (level, yaw relative to the base) and ``w_carry_offset``
(lateral and vertical offset from the base), both towards the nominal carry."""
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
    prob = dataclasses.replace(prob, options=prob.options.replaced(weights={"w_carry_pose": 50.0, "w_carry_offset": 20.0}))
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
    nominal = data.carry_rel["box"]
    for k in free:  # the nominal's yaw relative to the nominal base (the blend's, not the guess's)
        assert np.isfinite(nominal[k, 5]) and rel[k] == pytest.approx(math.remainder(nominal[k, 5], 2 * math.pi))


def test_cost_grows_with_tilt_relative_yaw_and_offset(s1):
    data, win, Pm, W0 = s1
    j = data.midx["box"]
    k = next(k for k in range(data.grid.K - 1) if data.obj_mode(k, "box") == "free")
    f = ca.Function("f", [win.a, win.b, win.p], [win.f])
    a, b = W0[:, k].copy(), W0[:, k + 1].copy()
    pose = np.arange(win.W.n)[win.W[f"o{j}_pose"]]
    x = a[win.W["x"]]
    rel = float(Pm[win.P[f"o{j}_yaw_rel"], k][0])
    off = Pm[win.P[f"o{j}_offset"], k]
    np.testing.assert_allclose(off, data.carry_rel["box"][k, 1:3])
    p_on, p_off = Pm[:, k].copy(), Pm[:, k].copy()
    p_off[win.P[f"o{j}_w_pose"]] = 0.0
    p_off[win.P[f"o{j}_w_offset"]] = 0.0
    w_stage = float(Pm[win.P["w_stage"], k][0])
    c, s = math.cos(x[5]), math.sin(x[5])

    def extra(roll=0.0, pitch=0.0, dyaw=0.0, ahead=0.4, dy=0.0, dz=0.0):
        aa = a.copy()
        ly, lz = off[0] + dy, off[1] + dz
        aa[pose[:3]] = x[:3] + [c * ahead - s * ly, s * ahead + c * ly, lz]
        aa[pose[3:6]] = [roll, pitch, x[5] + rel + dyaw]
        return float(f(aa, b, p_on)) - float(f(aa, b, p_off))

    assert extra() == pytest.approx(0.0, abs=1e-9)
    assert extra(ahead=0.3) == pytest.approx(0.0, abs=1e-9)   # the distance in front is free
    assert extra(dyaw=0.5) == pytest.approx(w_stage * 50 * 2 * (1 - math.cos(0.5)), rel=1e-9)
    assert extra(roll=0.1, pitch=-0.2) == pytest.approx(w_stage * 50 * (0.01 + 0.04), rel=1e-9)
    assert extra(dy=0.1, dz=-0.2) == pytest.approx(w_stage * 20 * (0.01 + 0.04), rel=1e-9)
    # periodic in the yaw: a full turn costs nothing
    assert extra(dyaw=2 * math.pi) == pytest.approx(0.0, abs=1e-9)
