"""execution: checks before anything moves, a real TO plan executed with logs/metrics, cancel, fall."""

import numpy as np
import pytest
from to_cases import simulation, solved, trajectory

from lomanip_sim.execution import Execution, ExecutionOptions, execution_error
from lomanip_sim.simulator import FallCriteria
from lomanip_sim.standing import StandingController
from lomanip_sim.trajectory import EXECUTION_FAILED, INVALID_TRAJECTORY, TrajectoryError, make_trajectory


def test_stand_plan_metrics_and_logs():
    sim, tr = simulation("case_stand")
    ex = Execution(sim, tr)
    feedback = []
    m = ex.run(on_feedback=lambda e: feedback.append(e.progress))
    assert m.task_success and not m.fell and not m.cancelled, m.task_success_detail
    assert m.duration == pytest.approx(tr.duration + ex.opt.settle_time, abs=0.03)
    assert m.max_base_position_error < 0.005 and m.rms_base_position_error <= m.max_base_position_error
    assert m.max_joint_error < 0.03 and m.qp_failures == 0
    assert m.max_unplanned_contact_force == 0.0 and m.unplanned_contact == ""  # feet only
    assert m.real_time_factor > 0.0  # measured (unpaced); its figure is tools/bench_exec.py's, not asserted here
    assert feedback[-1] == pytest.approx(1.0) and feedback == sorted(feedback)
    lg = ex.log
    n = len(lg.t)
    assert n == pytest.approx(m.duration * ex.opt.log_rate, abs=2)
    assert len(lg.qpos) == n and all(len(lg.measured[l]) == n for l in lg.measured)
    # the feet carry the robot's weight in the measured log
    fz = np.array(lg.measured["left_foot"])[:, 2] + np.array(lg.measured["right_foot"])[:, 2]
    assert np.all(fz[5:] > 250.0)


def test_refused_before_anything_moves():
    sim, tr = simulation("case_stand")
    far = make_trajectory(tr.t, _names(), tr.q, tr.qd, tr.base_pos + [0.5, 0.0, 0.0], tr.base_quat)
    before = sim.robot_qpos()
    with pytest.raises(TrajectoryError) as e:
        Execution(sim, far)
    assert e.value.code == INVALID_TRAJECTORY and "starts 0.50 m" in e.value.message
    assert sim.controller is sim.standing and sim.time == 0.0
    np.testing.assert_array_equal(sim.robot_qpos(), before)


def test_cancel_hands_over_to_standing():
    sim, tr = simulation("case_one_step")
    ex = Execution(sim, tr)
    m = ex.run(should_cancel=lambda: ex.time > 0.3)
    assert m.cancelled and not m.task_success and not m.fell
    assert isinstance(sim.controller, StandingController)
    sim.run_for(1.5)
    assert not sim.has_fallen() and sim.pelvis_height() > 0.7


def test_fall_is_detected_and_stops():
    sim, tr = simulation("case_stand")
    ex = Execution(sim, tr, options=ExecutionOptions(settle_time=3.0))
    ex.start()
    sim.run_for(0.2)
    sim.apply_external_force("pelvis", (600.0, 0.0, 0.0), 0.3)  # 180 N s: nobody stands that
    m = ex.run()
    assert m.fell and not m.task_success and "robot fell" in m.task_success_detail
    assert isinstance(sim.controller, StandingController)


def test_message_round_trip_matches_direct_conversion():
    from builtin_interfaces.msg import Time
    from lomanip_to import conversions as to_conv

    from lomanip_sim import conversions

    res, prob = solved("case_one_step")
    msg = to_conv.trajectory_msg(res, prob.phases, "case_one_step", Time())
    a, b = conversions.trajectory_from_msg(msg), trajectory("case_one_step")
    np.testing.assert_allclose(a.t, b.t, atol=1e-8)
    np.testing.assert_allclose(a.q, b.q, atol=1e-9)
    np.testing.assert_allclose(a.base_quat, b.base_quat, atol=1e-9)
    np.testing.assert_allclose(a.base_angvel, b.base_angvel, atol=1e-9)
    assert [sorted(p.contacts) for p in a.phases] == [sorted(p.contacts) for p in b.phases]
    for limb in b.forces:
        np.testing.assert_allclose(a.forces.get(limb, np.zeros_like(b.forces[limb])), b.forces[limb], atol=1e-9)
    np.testing.assert_allclose(a.angular_momentum, b.angular_momentum, atol=1e-9)
    msg.angular_momentum.pop()
    with pytest.raises(TrajectoryError, match="angular_momentum has"):
        conversions.trajectory_from_msg(msg)
    msg.angular_momentum.clear()  # optional: no momentum, no momentum task
    assert conversions.trajectory_from_msg(msg).angular_momentum is None
    msg.base_trajectory.points.pop()
    with pytest.raises(TrajectoryError, match="one time grid"):
        conversions.trajectory_from_msg(msg)


def test_free_objects_survive_the_message():
    """The schedule's object motions reach the controller: which objects each phase has free
    (carried by the contacts alone); a schedule with no object motions at all says nothing (None)."""
    from builtin_interfaces.msg import Time
    from lomanip_to import conversions as to_conv

    from lomanip_sim import conversions

    res, prob = solved("case_lift_box")
    msg = to_conv.trajectory_msg(res, prob.phases, "case_lift_box", Time())
    a, b = conversions.trajectory_from_msg(msg), trajectory("case_lift_box")
    assert [p.free_objects for p in a.phases] == [p.free_objects for p in b.phases]
    assert any(p.free_objects == frozenset({"box"}) for p in b.phases)
    assert any(p.free_objects == frozenset() for p in b.phases)
    for ph in msg.contact_schedule.phases:
        ph.object_motions.clear()
    assert all(p.free_objects is None for p in conversions.trajectory_from_msg(msg).phases)


def test_execution_error_wraps_unexpected():
    e = execution_error(RuntimeError("boom"))
    assert e.code == EXECUTION_FAILED and "boom" in e.message


def _names():
    from lomanip_sim.robot_model import G1_JOINT_NAMES

    return G1_JOINT_NAMES


def test_fall_thresholds_give_way_to_the_plan():
    """A plan that squats (S1: pelvis 0.30 m, torso 1.35 rad) is no fall; 15 cm below the plan is."""
    sim, tr = simulation("case_stand")
    ex = Execution(sim, tr)
    assert not ex._fallen(sim.data)
    sim.fall_criteria = FallCriteria(min_pelvis_height=0.9, max_tilt=0.0)  # the standing robot is past both...
    assert not ex._fallen(sim.data)  # ...but so is the plan (0.79 m, upright): 0.64 m and 0.4 rad count
    ex._plan_pose[:, 0] += 0.3  # a plan 30 cm higher than the robot
    assert ex._fallen(sim.data)


def test_unplanned_contacts_name_the_link_and_what_it_touches():
    """A robot dropped on its side: its torso lands on the floor, a contact the plan never has (only
    feet and hands make contacts); the feet's own contacts are not counted."""
    import mujoco

    sim, tr = simulation("case_stand")
    ex = Execution(sim, tr)
    m = sim.model
    d = mujoco.MjData(m)
    d.qpos[:] = sim.data.qpos
    d.qpos[2] = 0.10
    d.qpos[3:7] = [np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0]  # lying: turned 90 degrees about y
    mujoco.mj_forward(m, d)
    ex._unplanned_contacts(d)
    assert ex._max_unplanned == (0.0, "")  # at first only the soles touch the floor
    for _ in range(100):
        mujoco.mj_step(m, d)
    ex._unplanned_contacts(d)
    force, where = ex._max_unplanned
    assert force > 10.0 and "on floor" in where
    assert not any(link in where for link in ("ankle_roll", "wrist_yaw"))
