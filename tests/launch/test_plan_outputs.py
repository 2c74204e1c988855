"""Saving a plan result: arrays come back from the messages unchanged, files are written."""
from __future__ import annotations

import numpy as np
import yaml
from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point, Transform, Vector3
from trajectory_msgs.msg import JointTrajectoryPoint, MultiDOFJointTrajectoryPoint

from lomanip_launch.plan_outputs import error_name, save_plan, trajectory_arrays
from lomanip_msgs.action import Plan
from lomanip_msgs.msg import ContactWrench, ErrorCode, KnotWrenches, StageTiming


def _result(n: int = 5) -> Plan.Result:
    r = Plan.Result()
    r.error_code = ErrorCode(val=ErrorCode.SUCCESS, message="ok")
    jt = r.trajectory.joint_trajectory
    jt.joint_names = [f"j{i}" for i in range(3)]
    for k in range(n):
        t = 0.1 * k
        jt.points.append(JointTrajectoryPoint(positions=[t, 2 * t, 3 * t], velocities=[1.0, 2.0, 3.0],
                                              time_from_start=Duration(sec=0, nanosec=int(t * 1e9))))
        r.trajectory.base_trajectory.points.append(MultiDOFJointTrajectoryPoint(
            transforms=[Transform(translation=Vector3(x=t, y=0.0, z=0.79))]))
        r.trajectory.com_position.append(Point(z=0.7))
        r.trajectory.linear_momentum.append(Vector3(x=1.0))
        r.trajectory.angular_momentum.append(Vector3())
        w = ContactWrench(limb="left_foot")
        w.wrench.force.z = 100.0 + k
        r.trajectory.contact_wrenches.append(KnotWrenches(wrenches=[w]))
    r.timings = [StageTiming(stage="optimisation", seconds=1.5)]
    return r


def test_arrays_match_the_message():
    a = trajectory_arrays(_result().trajectory)
    np.testing.assert_allclose(a["t"], [0.0, 0.1, 0.2, 0.3, 0.4], atol=1e-9)
    np.testing.assert_allclose(a["q"][:, 1], 2 * a["t"], atol=1e-9)
    np.testing.assert_allclose(a["base_position"][:, 0], a["t"], atol=1e-9)
    np.testing.assert_allclose(a["contact_wrench"][:, 0, 2], 100.0 + np.arange(5))
    assert a["contact_wrench"][:, 1:].sum() == 0.0


def test_save_plan_writes_summary_arrays_and_plot(tmp_path):
    files = save_plan(tmp_path, ["pick up the box"], _result(), 3.0)
    names = {f.name for f in files}
    assert {"summary.yaml", "trajectory.npz", "trajectory.png"} <= names
    summary = yaml.safe_load((tmp_path / "summary.yaml").read_text())
    assert summary["error_code"] == "SUCCESS"
    assert summary["stage_timings_s"] == {"optimisation": 1.5}
    assert np.load(tmp_path / "trajectory.npz")["q"].shape == (5, 3)


def test_error_names():
    assert error_name(ErrorCode.TO_NOT_CONVERGED) == "TO_NOT_CONVERGED"
    assert error_name(12345) == "12345"


def test_summary_reports_an_execution_that_fell(tmp_path):
    """A run that fell ends with EXECUTION_FAILED before its execution timing; its metrics still count
    (the summary of such a demo run said "not executed")."""
    from lomanip_launch.plan_outputs import summary

    r = _result()
    assert summary(["p"], r, 1.0)["execution"] == "not executed (add --execute)"
    r.error_code = ErrorCode(val=ErrorCode.EXECUTION_FAILED, message="execution: the robot fell at t=5.08 s")
    r.execution.fell = True
    r.execution.duration = 5.08
    ex = summary(["p"], r, 1.0)["execution"]
    assert ex["fell"] is True and ex["duration_s"] == 5.08
