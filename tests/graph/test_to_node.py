"""The TO node as a real process: a small solve over DDS, the latched trajectory, bad requests."""
from __future__ import annotations

import math

import pytest

from .helpers import ros_process, wait_for, wait_for_service

pytestmark = pytest.mark.graph


@pytest.fixture(scope="module")
def to_node(tmp_path_factory):
    d = tmp_path_factory.mktemp("to")
    log = d / "to.log"
    with ros_process(["-m", "lomanip_to.to_node", "--ros-args", "-p", f"problem_dir:={d / 'problems'}"], log) as proc:
        yield proc, log


@pytest.fixture(scope="module")
def client():
    import rclpy

    rclpy.init()
    node = rclpy.create_node("to_test_client")
    yield node
    node.destroy_node()
    rclpy.try_shutdown()


def _spin(node):
    import rclpy

    return lambda: rclpy.spin_once(node, timeout_sec=0.05)


def _call(node, request, to_node, timeout=240.0):
    import rclpy

    from lomanip_msgs.srv import OptimizeTrajectory

    cli = node.create_client(OptimizeTrajectory, "/lomanip/to/optimize")
    proc, log = to_node
    wait_for_service(node, cli, 120, proc=proc, log_path=log)
    future = cli.call_async(request)
    rclpy.spin_until_future_complete(node, future, timeout_sec=timeout)
    assert future.done(), "no answer"
    return future.result()


def _request(name):
    from lomanip_to import conversions as conv
    from lomanip_to.fixtures import load_problem
    from lomanip_to.solver import default_model

    model = default_model()
    return conv.request_from_problem(load_problem(name, model=model), model.joint_names)


def test_one_step_is_solved_published_and_physically_consistent(to_node, client):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from lomanip_msgs.msg import ErrorCode, WholeBodyTrajectory

    req = _request("case_one_step")
    res = _call(client, req, to_node)
    assert res.error_code.val == ErrorCode.SUCCESS, res.error_code.message
    # the request's problem was saved for offline re-runs (problem_dir)
    import pickle

    saved = sorted((to_node[1].parent / "problems").glob("to_problem_*.pkl"))
    assert saved, "problem_dir holds no problem"
    prob = pickle.loads(saved[0].read_bytes())
    assert len(prob.phases) == len(req.contact_schedule.phases)
    # and beside it the solver's result, which replays the request (tools/exec_trace.py runs/<run>)
    from lomanip_to.result import TOResult

    replay = TOResult.load(saved[0].with_name(saved[0].name.replace("problem", "result").replace(".pkl", ".npz")))
    assert replay.stats.converged and replay.stats.iterations == res.trajectory.solver_statistics.iterations
    traj = res.trajectory
    stats = traj.solver_statistics
    assert stats.converged and stats.max_penetration <= 5e-3
    n = len(traj.joint_trajectory.points)
    assert n > 10 and len(traj.base_trajectory.points) == n == len(traj.com_position) == len(traj.contact_wrenches)
    assert traj.joint_trajectory.joint_names[0] == "left_hip_pitch_joint" and len(traj.joint_trajectory.joint_names) == 29
    times = [p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in traj.joint_trajectory.points]
    assert all(b > a for a, b in zip(times, times[1:]))
    # Feet carry the weight: total vertical contact force ~ m g on average over the motion.
    fz = [sum(w.wrench.force.z for w in k.wrenches) for k in traj.contact_wrenches]
    assert sum(fz) / len(fz) == pytest.approx(33.34 * 9.81, rel=0.1)
    # A late subscriber still gets it (transient local).
    got = []
    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    sub = client.create_subscription(WholeBodyTrajectory, "/lomanip/trajectory", got.append, qos)
    wait_for(lambda: got, 30, "latched trajectory", spin=_spin(client))
    client.destroy_subscription(sub)
    assert len(got[0].joint_trajectory.points) == n


def test_bad_requests_get_codes_before_solving(to_node, client):
    from lomanip_msgs.msg import ErrorCode

    req = _request("case_lift_box")
    req.keyframes.keyframes[0].contacts[0].object_id = "refrigerator"
    res = _call(client, req, to_node, timeout=30)
    assert res.error_code.val == ErrorCode.UNKNOWN_OBJECT and "refrigerator" in res.error_code.message

    req = _request("case_lift_box")
    req.keyframes.keyframes[0].joints.position[3] = math.nan
    res = _call(client, req, to_node, timeout=30)
    assert res.error_code.val == ErrorCode.INVALID_REQUEST and "NaN" in res.error_code.message

    req = _request("case_lift_box")
    phases = req.contact_schedule.phases
    phases[1].start = phases[0].start   # overlaps the first phase
    res = _call(client, req, to_node, timeout=30)
    assert res.error_code.val == ErrorCode.INVALID_REQUEST and "overlap" in res.error_code.message

    from lomanip_msgs.msg import SolverOption

    req = _request("case_lift_box")
    req.options.solver_options = [SolverOption(name="perturb_always_cd", value="maybe")]
    res = _call(client, req, to_node, timeout=30)
    assert res.error_code.val == ErrorCode.INVALID_REQUEST and "perturb_always_cd" in res.error_code.message
    assert to_node[0].poll() is None


def test_progress_is_published_during_a_solve(to_node, client):
    """/lomanip/to/progress: SolverStatistics per iteration (rate-limited) while the solve runs."""
    from lomanip_msgs.msg import ErrorCode, SolverStatistics

    got = []
    sub = client.create_subscription(SolverStatistics, "/lomanip/to/progress", got.append, 50)
    wait_for(lambda: client.count_publishers("/lomanip/to/progress") > 0, 30, "progress publisher",
             spin=_spin(client))
    res = _call(client, _request("case_stand"), to_node)
    client.destroy_subscription(sub)
    assert res.error_code.val == ErrorCode.SUCCESS, res.error_code.message
    assert got, "no progress message during the solve"
    its = [m.iterations for m in got]
    assert its[0] >= 1 and its == sorted(its) and its[-1] <= res.trajectory.solver_statistics.iterations
    assert all(not m.converged and m.status_message for m in got)
    assert all(m.solve_time >= 0 and math.isfinite(m.cost) for m in got)


def test_cancel_stops_a_running_solve_and_the_node_serves_the_next(to_node, client):
    """/lomanip/to/cancel (std_srvs/Trigger) kills the solver worker: the request gets CANCELLED."""
    import rclpy
    from std_srvs.srv import Trigger

    from lomanip_msgs.msg import ErrorCode, SolverStatistics
    from lomanip_msgs.srv import OptimizeTrajectory

    cancel = client.create_client(Trigger, "/lomanip/to/cancel")
    wait_for(cancel.service_is_ready, 30, "/lomanip/to/cancel", spin=_spin(client))
    idle = cancel.call_async(Trigger.Request())
    rclpy.spin_until_future_complete(client, idle, timeout_sec=10)
    assert idle.result().success is False and "no optimisation" in idle.result().message

    got = []
    sub = client.create_subscription(SolverStatistics, "/lomanip/to/progress", got.append, 50)
    cli = client.create_client(OptimizeTrajectory, "/lomanip/to/optimize")
    future = cli.call_async(_request("case_lift_box"))
    wait_for(lambda: got, 120, "first progress message", spin=_spin(client))
    stop = cancel.call_async(Trigger.Request())
    rclpy.spin_until_future_complete(client, stop, timeout_sec=10)
    assert stop.result().success
    rclpy.spin_until_future_complete(client, future, timeout_sec=15)
    client.destroy_subscription(sub)
    assert future.done(), "the cancelled solve did not answer"
    assert future.result().error_code.val == ErrorCode.CANCELLED, future.result().error_code.message
    res = _call(client, _request("case_stand"), to_node)   # a fresh worker solves the next one
    assert res.error_code.val == ErrorCode.SUCCESS, res.error_code.message
