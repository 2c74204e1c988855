"""The whole graph as a user starts it (`lomanip up --record`), used from other processes.

Bad requests go through every real stage that should catch them (planner, perception, TO) and the
graph keeps serving. The heavy case (marked slow) runs examples/plan_client.py, a client written
only against lomanip_msgs, which gets a trajectory from /lomanip/plan and on /lomanip/trajectory;
the bag of the run then reads back with rosbags.

Scene: S2 with the trolley right in front of the robot (two steps, then a push: a 4.6 s horizon).
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from .helpers import ROOT, graph_env, ros_process, wait_for, wait_for_service

pytestmark = pytest.mark.graph

SCENE = ["--scenario", "s2_trolley", "--set", "trolley_position=[0.85, 0.0]", "--set", "table_position=[0.75, 1.6]",
         "--set", "camera_position=[2.9, 1.7, 1.9]", "--set", "camera_target=[0.7, -0.5, 0.6]"]   # as make demo
PUSH = ["push the trolley forward"]


@pytest.fixture(scope="module")
def graph(tmp_path_factory):
    d = tmp_path_factory.mktemp("e2e")
    log = d / "lomanip.log"
    with ros_process(["-m", "lomanip_launch.cli", "up", *SCENE, "--record", str(d / "bag"), "--run-dir", str(d)],
                     log) as proc:
        wait_for(lambda: "graph is up" in log.read_text(), 180, "the graph", proc=proc, log_path=log)
        yield proc, d


@pytest.fixture(scope="module")
def client(graph):
    import rclpy

    rclpy.init()
    node = rclpy.create_node("e2e_test_client")
    yield node
    node.destroy_node()
    rclpy.try_shutdown()


def _plan(node, request, timeout=600.0):
    import rclpy

    from lomanip_msgs.srv import PlanTask

    cli = node.create_client(PlanTask, "/lomanip/plan")
    wait_for_service(node, cli)
    future = cli.call_async(request)
    rclpy.spin_until_future_complete(node, future, timeout_sec=timeout)
    assert future.done(), f"/lomanip/plan did not answer within {timeout} s"
    node.destroy_client(cli)
    return future.result()


def test_bad_requests_get_their_code_and_the_graph_keeps_serving(graph, client):
    from lomanip_msgs.msg import ErrorCode, PlacementGoal, TrajectoryOptions
    from lomanip_msgs.srv import PlanTask

    proc, _ = graph
    res = _plan(client, PlanTask.Request(prompts=[]))
    assert res.error_code.val == ErrorCode.INVALID_REQUEST and "prompts" in res.error_code.message
    res = _plan(client, PlanTask.Request(prompts=["push the refrigerator"]))
    assert res.error_code.val == ErrorCode.UNKNOWN_OBJECT and "refrigerator" in res.error_code.message
    res = _plan(client, PlanTask.Request(prompts=PUSH, placement_goals=[PlacementGoal(object_id="piano")]))
    assert res.error_code.val == ErrorCode.UNKNOWN_OBJECT and "piano" in res.error_code.message
    # A TO that may not finish: the failure is named, with the worst violation, and nothing is marked good.
    res = _plan(client, PlanTask.Request(prompts=PUSH, options=TrajectoryOptions(max_iterations=2)))
    assert res.error_code.val == ErrorCode.TO_NOT_CONVERGED, res.error_code.message
    assert "did not converge" in res.error_code.message and "max constraint violation" in res.error_code.message
    assert [t.stage for t in res.timings][-3:] == ["perception", "retargeting", "optimisation"]
    assert len(res.keyframes.keyframes) == 1 and len(res.contacts.subtasks) == 1
    assert proc.poll() is None


@pytest.mark.slow
@pytest.mark.timeout(2400)  # a whole TO solve through the graph: minutes on 2 shared cores
def test_a_client_process_gets_the_trajectory_and_the_bag_reads_back(graph):
    proc, d = graph
    env = graph_env()
    out = subprocess.run([sys.executable, str(ROOT / "examples/plan_client.py"), *PUSH], env=env, capture_output=True,
                         text=True, timeout=1800)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "trajectory:" in out.stdout and "29 joints" in out.stdout and "'trolley'" in out.stdout
    time.sleep(1.0)   # let the recorder write the latched trajectory
    os.killpg(proc.pid, signal.SIGINT)
    proc.wait(60)
    assert proc.returncode == 0, (d / "lomanip.log").read_text()[-3000:]

    from rosbags.highlevel import AnyReader

    from lomanip_launch.bag import make_typestore

    with AnyReader([d / "bag"], default_typestore=make_typestore()) as reader:
        conns = [c for c in reader.connections if c.topic == "/lomanip/trajectory"]
        assert conns, sorted({c.topic for c in reader.connections})
        msgs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=conns)]
    assert len(msgs) == 1
    traj = msgs[0]
    assert len(traj.joint_trajectory.joint_names) == 29 and len(traj.joint_trajectory.points) > 100
    assert traj.solver_statistics.converged
