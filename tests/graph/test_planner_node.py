"""The plan service/action as real processes: bad input, a missing stage, busy, cancel.

Perception is played by a stand-in service in the test process so each case is controlled; the
full pipeline with the real perception node is exercised in the end-to-end test.
"""
from __future__ import annotations

import threading
import time

import pytest

from .helpers import call_idempotent, ros_process, wait_for, wait_for_service

pytestmark = pytest.mark.graph


@pytest.fixture(scope="module")
def graph(tmp_path_factory):
    d = tmp_path_factory.mktemp("planner")
    with ros_process(["-m", "lomanip_sim.sim_node", "--ros-args", "-p", "camera_rate:=2.0"], d / "sim.log") as sim, \
         ros_process(["-m", "lomanip_planner.planner_node", "--ros-args", "-p", "perception_timeout:=8.0"],
                     d / "planner.log") as planner:
        yield sim, planner, d


@pytest.fixture(scope="module")
def node(graph):
    import rclpy
    from sensor_msgs.msg import JointState

    rclpy.init()
    n = rclpy.create_node("planner_test_client")
    # The planner needs the sim's state first; wait for it like a user's client would.
    got = []
    sub = n.create_subscription(JointState, "/joint_states", got.append, 10)
    wait_for(lambda: got, 90, "/joint_states", spin=lambda: rclpy.spin_once(n, timeout_sec=0.05),
             proc=graph[0], log_path=graph[2] / "sim.log")
    n.destroy_subscription(sub)
    time.sleep(0.5)
    yield n
    n.destroy_node()
    rclpy.try_shutdown()


def _plan(node, prompts, timeout=60.0):
    """These requests end quickly in an error, so a re-send (see call_idempotent) is harmless."""
    from lomanip_msgs.srv import PlanTask

    cli = node.create_client(PlanTask, "/lomanip/plan")
    try:
        return call_idempotent(node, cli, PlanTask.Request(prompts=prompts), timeout=timeout, attempt=20.0)
    finally:
        node.destroy_client(cli)


def test_empty_prompt_list_is_invalid(graph, node):
    from lomanip_msgs.msg import ErrorCode

    res = _plan(node, [])
    assert res.error_code.val == ErrorCode.INVALID_REQUEST and "prompts" in res.error_code.message
    res = _plan(node, ["pick up the box", "  "])
    assert res.error_code.val == ErrorCode.INVALID_REQUEST


def test_missing_perception_is_reported_not_hung(graph, node):
    from lomanip_msgs.msg import ErrorCode

    t0 = time.monotonic()
    res = _plan(node, ["pick up the box"])
    assert res.error_code.val == ErrorCode.NOT_READY, res.error_code.message
    assert "/lomanip/perception/extract_contacts" in res.error_code.message
    assert time.monotonic() - t0 < 20


def test_second_request_while_planning_is_busy_and_the_first_is_unharmed(graph, node):
    """A slow stand-in perception keeps plan 1 running; plan 2 gets BUSY; plan 1 ends with the
    stand-in's own error code."""
    import rclpy
    from rclpy.executors import MultiThreadedExecutor

    from lomanip_msgs.msg import ErrorCode
    from lomanip_msgs.srv import ExtractContacts, PlanTask

    def slow_failure(request, response):
        # long enough for the second request (sent after 1 s) to find plan 1 running, well inside
        # the planner's 8 s perception timeout even on a loaded machine (4 s was flaky)
        time.sleep(3.0)
        response.error_code = ErrorCode(val=ErrorCode.NO_HUMAN_FOUND, message="stand-in: no person in subtask 0")
        return response

    fake = rclpy.create_node("fake_perception")
    fake.create_service(ExtractContacts, "/lomanip/perception/extract_contacts", slow_failure)
    executor = MultiThreadedExecutor()
    executor.add_node(fake)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        cli = node.create_client(PlanTask, "/lomanip/plan")
        wait_for_service(node, cli)
        first = cli.call_async(PlanTask.Request(prompts=["pick up the box"]))
        time.sleep(1.0)
        second = cli.call_async(PlanTask.Request(prompts=["pick up the box"]))
        rclpy.spin_until_future_complete(node, second, timeout_sec=20)
        assert second.result().error_code.val == ErrorCode.BUSY
        rclpy.spin_until_future_complete(node, first, timeout_sec=30)
        res = first.result()
        assert res.error_code.val == ErrorCode.NO_HUMAN_FOUND and "subtask 0" in res.error_code.message
        assert [t.stage for t in res.timings] == ["perception"]
    finally:
        executor.shutdown()
        fake.destroy_node()
    assert graph[1].poll() is None
