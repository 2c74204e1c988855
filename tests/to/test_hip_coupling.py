"""The coupled hip limit keeps the hip-roll link off the pelvis on MuJoCo's meshes, and the TO holds it."""
import casadi as ca
import mujoco
import numpy as np
import pytest

from lomanip_sim.robot_model import load_g1_model
from lomanip_to import solver
from lomanip_to.checks import joint_limit_violation
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem
from lomanip_to.hip_coupling import HIP_JOINTS, hip_roll_bound, hip_roll_clearance

PITCHES = np.linspace(-2.53, -0.8, 24)


@pytest.fixture(scope="module")
def mesh():
    m = load_g1_model()
    return m, mujoco.MjData(m)


def _pelvis_thigh_distance(m, d, side: str, pitch: float, roll: float) -> float:
    """Least distance (m) between the pelvis mesh and the hip-roll / hip-yaw link meshes."""
    d.qpos[:] = m.qpos0
    d.qpos[2] = 2.0
    d.qpos[m.joint(f"{side}_hip_pitch_joint").qposadr[0]] = pitch
    d.qpos[m.joint(f"{side}_hip_roll_joint").qposadr[0]] = roll
    mujoco.mj_kinematics(m, d)

    def geoms(body):
        b = m.body(body).id
        return [g for g in range(m.ngeom) if m.geom_bodyid[g] == b and m.geom_contype[g]]

    thigh = geoms(f"{side}_hip_roll_link") + geoms(f"{side}_hip_yaw_link")
    return min(mujoco.mj_geomDistance(m, d, a, b, 0.2, None) for a in geoms("pelvis") for b in thigh)


@pytest.mark.parametrize("side", ["left", "right"])
def test_the_bound_is_collision_free_and_tight_on_the_meshes(mesh, side):
    m, d = mesh
    sign = HIP_JOINTS[side][2]
    lo, hi = m.joint(f"{side}_hip_roll_joint").range
    touching = 0
    for p in PITCHES:
        b = float(hip_roll_bound(p))
        for extra in (0.0, 0.1, 0.3):
            roll = sign * (b + extra)
            if lo <= roll <= hi:
                assert _pelvis_thigh_distance(m, d, side, p, roll) >= 0.0, (side, p, roll)
        # 0.1 rad past the bound the meshes meet wherever the bound is above the joint range
        roll = sign * (b - 0.1)
        if lo <= roll <= hi:
            touching += 1
            assert _pelvis_thigh_distance(m, d, side, p, roll) < 0.0, (side, p, roll)
    assert touching >= 10  # the sweep does reach the deep flexion where the bound acts


def test_the_hip_indices_name_the_hip_joints(g1):
    for side, (pitch, roll, _) in HIP_JOINTS.items():
        assert g1.joint_names[pitch] == f"{side}_hip_pitch_joint"
        assert g1.joint_names[roll] == f"{side}_hip_roll_joint"


def test_symbolic_and_numeric_clearance_agree():
    rng = np.random.default_rng(3)
    x = ca.SX.sym("q", 29)
    f = ca.Function("c", [x], [hip_roll_clearance(x)])
    for _ in range(5):
        q = rng.uniform(-2.5, 0.5, 29)
        np.testing.assert_allclose(np.array(f(q)).ravel(), hip_roll_clearance(q), atol=1e-12)
    q = np.zeros(29)
    q[0], q[1] = -2.0, -0.45  # S1's pick-up squat before the bound (left hip)
    assert hip_roll_clearance(q)[0] < -0.4


def test_every_knot_after_the_start_holds_the_bound(g1):
    data = ProblemData(load_problem("s1_basket", model=g1), g1)
    win, _ = solver.get_window(g1, data.structure)
    _, _, lbg, ubg, _, _ = data.fill(win, *solver.homotopy_stages(data.prob.options)[-1])
    rows = win.G["hip roll coupling"]
    assert rows.stop - rows.start == 2
    assert np.all(lbg[rows, 0] == -np.inf)  # the measured start
    assert np.all(lbg[rows, 1:] == 0.0) and np.all(ubg[rows, 1:] == np.inf)


def test_the_joint_limit_check_reports_the_coupling(g1):
    class Res:
        t_knots = np.array([0.0, 0.2])
        x_knots = np.zeros((2, 35))

    res = Res()
    res.x_knots[:, 6:] = (g1.q_lower + g1.q_upper) / 2
    res.x_knots[:, 6 + 0], res.x_knots[:, 6 + 1] = -2.0, -0.3
    v, (name, t) = joint_limit_violation(g1, res)
    assert name == "left hip roll coupling" and t == 0.2
    assert v == pytest.approx(-hip_roll_clearance(res.x_knots[1, 6:])[0])


def test_hip_margin_moves_the_coupling_rows_inside_the_bound(g1):
    """``weights: {hip_margin: m}`` (rad) asks the hip roll to stay m inside the bound: the rows of
    the same state are lower by exactly m (0, the default, is the bound itself)."""
    import dataclasses

    prob = load_problem("s1_basket", model=g1)
    rows = {}
    for margin in (0.0, 0.08):
        opts = dataclasses.replace(prob.options, weights={**prob.options.weights, "hip_margin": margin})
        data = ProblemData(dataclasses.replace(prob, options=opts), g1)
        win, _ = solver.get_window(g1, data.structure)
        _, _, _, _, P, W0 = data.fill(win, *solver.homotopy_stages(opts)[-1])
        assert np.all(P[win.P["hip_margin"]] == margin)
        g = ca.Function("g", [win.a, win.b, win.p], [win.g])
        rows[margin] = np.array(g(W0[:, 3], W0[:, 4], P[:, 3])).ravel()[win.G["hip roll coupling"]]
    assert np.allclose(rows[0.0] - rows[0.08], 0.08)
