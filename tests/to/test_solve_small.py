"""Small whole-body TO cases solved end to end, checked for physical consistency (each < ~30 s)."""
import numpy as np
import pytest

from lomanip_to import solver
from lomanip_to.checks import TOL
from lomanip_to.fixtures import load_problem


def _assert_physical(res):
    s = res.stats
    assert s.converged, s.status_message()
    assert s.max_dynamics_violation.value < 1e-4, s.max_dynamics_violation.text()
    assert s.max_contact_violation.value < 1e-4, s.max_contact_violation.text()
    for name, c in s.checks.items():
        assert c["ok"], f"{name}: {c}"
    assert s.max_penetration <= TOL["penetration"]
    assert res.success


def _assert_dense(res, g1):
    assert res.t[0] == 0.0 and abs(res.t[-1] - res.t_knots[-1]) < 1e-9
    assert np.allclose(np.diff(res.t)[:-1], 0.01)
    n = len(res.t)
    assert res.joint_positions.shape == (n, 29) and res.joint_velocities.shape == (n, 29)
    assert res.base_quat_xyzw.shape == (n, 4)
    assert np.allclose(np.linalg.norm(res.base_quat_xyzw, axis=1), 1.0)
    for limb in res.limbs:
        assert res.forces[limb].shape == (n, 3)
    assert res.com.shape == (n, 3) and res.angular_momentum.shape == (n, 3)
    # the dense grid passes through the knots
    i = np.searchsorted(res.t, res.t_knots[3])
    assert np.allclose(res.joint_positions[i], res.x_knots[3, 6:], atol=1e-9)


def test_stand_still(g1):
    res = solver.solve(load_problem("case_stand", model=g1), g1)
    _assert_physical(res)
    _assert_dense(res, g1)
    # total vertical force = weight
    fz = sum(res.forces_knots[f][:, 2] for f in ("left_foot", "right_foot"))
    assert np.allclose(fz, g1.mass * 9.81, rtol=1e-3)
    assert res.stats.iterations < 100  # its time is measured in tools/bench_to.py, not asserted here


def test_one_step(g1):
    res = solver.solve(load_problem("case_one_step", model=g1), g1)
    _assert_physical(res)
    lf = res.points_knots["left_foot"]
    # the left foot moved forward, the right one did not
    assert lf[-1, 0] - lf[0, 0] > 0.07  # mid-foot pulled towards +0.1 m by eq. (2)
    rf = res.points_knots["right_foot"]
    assert np.linalg.norm(rf[-1] - rf[0]) < 1e-3
    # swing: left foot has no force while it is in the air
    swing = [k for k, o in enumerate(res.contact_objects_knots["left_foot"]) if not o]
    assert swing and np.allclose(res.forces_knots["left_foot"][swing], 0.0)
    assert res.points_knots["left_foot"][swing, 2].max() > 0.02
    # the lift-off knot is still planted (its last force acts until then), and so is the dense grid
    # up to it: no loaded foot sliding into the swing
    lift = swing[0]
    assert np.linalg.norm(lf[lift] - lf[lift - 1]) < 1e-3
    dense = [k for k in range(len(res.t)) if res.t_knots[lift - 1] <= res.t[k] <= res.t_knots[lift]]
    x = np.hstack([res.base_position, np.zeros((len(res.t), 3)), res.joint_positions])
    from lomanip_to.model import quat_xyzw_to_rot, rot_to_rpy

    x[:, 3:6] = [rot_to_rpy(quat_xyzw_to_rot(q)) for q in res.base_quat_xyzw]
    feet = np.array([g1.numeric(x[k])["limbs"]["left_foot"][0] for k in dense])
    assert np.abs(feet - lf[lift - 1]).max() < 3e-3


def test_lift_light_box(g1):
    prob = load_problem("case_lift_box", model=g1)
    res = solver.solve(prob, g1)
    _assert_physical(res)
    box = res.object_pose_knots["box"]
    assert box[-1, 2] - box[0, 2] > 0.08  # lifted ~10 cm
    # the carried box never dips into the floor: its bottom corners stay at z >= 0
    from lomanip_to.model import rpy_to_rot

    corners = prob.object("box").bottom_corners()
    for pose in box:
        assert np.all(pose[2] + corners @ rpy_to_rot(pose[3:6])[2] >= -1e-4)
    # Newton's third law: while free, the box's momentum changes by gravity + the hands' reaction
    k = len(res.t_knots) - 3
    t = res.t_knots
    vel = res.object_vel_knots["box"]
    f_on_box = -(res.forces_knots["left_hand"][k] + res.forces_knots["right_hand"][k])
    m_box = prob.object("box").mass
    acc = (vel[k + 1, :3] - vel[k, :3]) / (t[k + 1] - t[k])
    assert np.allclose(m_box * acc, f_on_box + m_box * np.array([0, 0, -9.81]), atol=1e-3)
    # hands are patch contacts: their moments stay inside the patch's wrench bounds
    from lomanip_to.transcription import HAND_PATCH_HALF, HAND_TORSION

    for h in ("left_hand", "right_hand"):
        for k in range(len(t)):
            n = res.normals_knots[h][k]
            if not np.any(n):
                assert np.allclose(res.torques_knots[h][k], 0.0)
                continue
            fn = float(res.forces_knots[h][k] @ n)
            tau = res.torques_knots[h][k]
            assert abs(tau @ n) <= HAND_TORSION * fn + 1e-3
            assert np.linalg.norm(tau - (tau @ n) * n) <= np.sqrt(2) * HAND_PATCH_HALF * fn + 1e-3


def test_failed_solve_is_reported_as_failed(g1):
    prob = load_problem("case_one_step", model=g1, options={"max_iterations": 3})
    res = solver.solve(prob, g1)
    assert not res.stats.converged
    assert not res.success
    assert "did not converge in" in res.stats.status_message()


def test_solver_cache_is_bounded(g1, monkeypatch):
    """A long-running TO node keeps at most MAX_CACHED_SOLVERS solvers (one per active-row set)."""
    monkeypatch.setattr(solver, "MAX_CACHED_SOLVERS", 1)
    monkeypatch.setattr(solver, "_SOLVERS", {})
    monkeypatch.setattr(solver, "_CALLBACKS", {})
    res = solver.solve(load_problem("case_stand", model=g1), g1)
    assert res.success
    assert len(solver._SOLVERS) <= 1
