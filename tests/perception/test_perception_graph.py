"""The perception node as a real process beside the sim node: S1/S2 prompt lists and bad inputs."""
from __future__ import annotations

import numpy as np
import pytest

from tests.graph.helpers import call_idempotent, ros_process, wait_for

pytestmark = pytest.mark.graph

S1 = ["pick up the box", "place the box next to the shelf", "step on the box and grab the basket"]
S2 = ["pick up the box from the table", "place the box on the trolley", "push the trolley forward"]
EXPECTED = {  # subtask -> {limb: object id}
    "s1_basket": [{"left_hand": "box", "right_hand": "box"}, {"left_hand": "box", "right_hand": "box"},
                  {"left_foot": "box", "right_foot": "box", "left_hand": "basket", "right_hand": "basket"}],
    "s2_trolley": [{"left_hand": "box", "right_hand": "box"}, {"left_hand": "box", "right_hand": "box"},
                   {"left_hand": "trolley", "right_hand": "trolley"}],
}


@pytest.fixture(scope="module")
def client():
    import rclpy

    rclpy.init()
    node = rclpy.create_node("perception_test_client")
    yield node
    node.destroy_node()
    rclpy.try_shutdown()


def _call(node, client, request, timeout=120.0, attempt=60.0):
    """Extracting contacts may be repeated; a lost first response is re-sent (call_idempotent)."""
    return call_idempotent(node, client, request, timeout=timeout, attempt=attempt)


@pytest.mark.parametrize("scenario,prompts", [("s1_basket", S1), ("s2_trolley", S2)])
def test_extract_contacts_with_sim(scenario, prompts, client, tmp_path):
    from lomanip_msgs.msg import ContactSet, ErrorCode
    from lomanip_msgs.srv import ExtractContacts
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from visualization_msgs.msg import MarkerArray

    sim_log, perc_log = tmp_path / "sim.log", tmp_path / "perception.log"
    with ros_process(["-m", "lomanip_sim.sim_node", "--ros-args", "-p", f"scenario:={scenario}",
                      "-p", "camera_rate:=2.0"], sim_log) as sim, \
            ros_process(["-m", "lomanip_perception.perception_node"], perc_log) as perc:  # fmt: skip
        cli = client.create_client(ExtractContacts, "/lomanip/perception/extract_contacts")
        wait_for(lambda: cli.service_is_ready(), 60, "extract_contacts service", proc=perc, log_path=perc_log)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        got = {}
        client.create_subscription(ContactSet, "/lomanip/contacts", lambda m: got.__setitem__("contacts", m), latched)
        client.create_subscription(MarkerArray, "/lomanip/perception/contact_markers", lambda m: got.__setitem__("markers", m), latched)

        res = _call(client, cli, ExtractContacts.Request(prompts=prompts))
        assert res.error_code.val == ErrorCode.SUCCESS, res.error_code.message + "\n" + perc_log.read_text()[-2000:]
        assert len(res.contacts.subtasks) == len(prompts)
        for sub, expected in zip(res.contacts.subtasks, EXPECTED[scenario]):
            found = {c.limb: c.object_id for c in sub.contacts if c.object_id != "floor"}
            assert found == expected, (sub.prompt, found)
            for c in sub.contacts:
                p = np.array([c.position.x, c.position.y, c.position.z])
                assert np.all(np.isfinite(p)) and 0.0 <= c.confidence <= 1.0
        assert len(res.human_poses) == len(prompts) and all(len(h.keypoints) > 10 for h in res.human_poses)
        stages = {t.stage for t in res.timings}
        assert "subtask0/contact_transfer" in stages and "total" in stages
        import rclpy

        wait_for(lambda: "contacts" in got and "markers" in got, 10, "latched contacts and markers",
                 spin=lambda: rclpy.spin_once(client, timeout_sec=0.05))  # fmt: skip
        assert len(got["contacts"].subtasks) == len(prompts) and len(got["markers"].markers) > 3

        if scenario == "s1_basket":
            _bad_inputs(client, cli, perc)
        assert sim.poll() is None and perc.poll() is None


def _bad_inputs(client, cli, perc):
    from lomanip_msgs.msg import ErrorCode
    from lomanip_msgs.srv import ExtractContacts

    res = _call(client, cli, ExtractContacts.Request(prompts=[]))
    assert res.error_code.val == ErrorCode.INVALID_REQUEST and "empty prompt list" in res.error_code.message

    res = _call(client, cli, ExtractContacts.Request(prompts=["pick up the box", "push the refrigerator"]))
    assert res.error_code.val == ErrorCode.UNKNOWN_OBJECT
    assert "subtask 1 'push the refrigerator'" in res.error_code.message and "refrigerator" in res.error_code.message

    # an explicit frame whose depth is all NaN
    req = ExtractContacts.Request(prompts=["pick up the box"])
    req.rgb.height, req.rgb.width, req.rgb.encoding, req.rgb.step = 4, 4, "rgb8", 12
    req.rgb.data = bytes(48)
    req.depth.height, req.depth.width, req.depth.encoding, req.depth.step = 4, 4, "32FC1", 16
    req.depth.data = np.full((4, 4), np.nan, np.float32).tobytes()
    req.camera_info.width, req.camera_info.height = 4, 4
    req.camera_info.k = [2.0, 0.0, 2.0, 0.0, 2.0, 2.0, 0.0, 0.0, 1.0]
    req.camera_pose.orientation.w = 1.0
    res = _call(client, cli, req)
    assert res.error_code.val == ErrorCode.INVALID_REQUEST and "NaN" in res.error_code.message

    # finite depth but the box is not in view: empty mask, named by subtask
    req.depth.data = np.full((4, 4), 50.0, np.float32).tobytes()
    res = _call(client, cli, req)
    assert res.error_code.val == ErrorCode.CONTACT_TRANSFER_FAILED
    assert "subtask 0 'pick up the box'" in res.error_code.message

    # still serving
    res = _call(client, cli, ExtractContacts.Request(prompts=["pick up the box"]))
    assert res.error_code.val == ErrorCode.SUCCESS and perc.poll() is None


def test_planner_gets_contacts_from_the_perception_node(client, tmp_path):
    """The planner's perception call over DDS (sim + perception + planner, no TO node): the plan
    carries the perception contacts and keyframes retargeted from them, then stops at the missing
    optimiser with NOT_READY naming its service."""
    from lomanip_msgs.msg import ErrorCode
    from lomanip_msgs.srv import PlanTask

    logs = {n: tmp_path / f"{n}.log" for n in ("sim", "perception", "planner")}
    with ros_process(["-m", "lomanip_sim.sim_node", "--ros-args", "-p", "scenario:=s2_trolley",
                      "-p", "camera_rate:=2.0"], logs["sim"]) as sim, \
            ros_process(["-m", "lomanip_perception.perception_node"], logs["perception"]) as perc, \
            ros_process(["-m", "lomanip_planner.planner_node", "--ros-args", "-p", "optimisation_timeout:=2.0"],
                        logs["planner"]) as planner:  # fmt: skip
        cli = client.create_client(PlanTask, "/lomanip/plan")
        wait_for(lambda: cli.service_is_ready(), 60, "plan service", proc=planner, log_path=logs["planner"])
        from geometry_msgs.msg import Point
        from lomanip_launch.task_file import load_task
        from lomanip_msgs.msg import PlacementGoal

        task = load_task("s2_trolley")  # the S2 task file: its prompts and the box's placement goal
        assert list(task.prompts) == S2
        goals = [PlacementGoal(object_id=g.object_id, position=Point(x=g.position[0], y=g.position[1], z=g.position[2]),
                               yaw=g.yaw) for g in task.placement_goals]  # fmt: skip
        res = _call(client, cli, PlanTask.Request(prompts=S2, placement_goals=goals), timeout=240.0, attempt=240.0)
        text = "\n".join(p.read_text()[-1500:] for p in logs.values())
        assert [len(s.contacts) for s in res.contacts.subtasks] and len(res.contacts.subtasks) == len(S2), text
        for sub, expected in zip(res.contacts.subtasks, EXPECTED["s2_trolley"]):
            assert {c.limb: c.object_id for c in sub.contacts if c.object_id != "floor"} == expected
        assert len(res.human_poses) == len(S2)
        stages = [t.stage for t in res.timings]
        assert stages[:1] == ["perception"], (stages, res.error_code.message, text)
        print("plan stages", stages, "->", res.error_code.message)
        # retargeting consumed the perception contacts; the plan then stops at the missing optimiser
        assert res.error_code.val == ErrorCode.NOT_READY, (res.error_code.message, text)
        assert stages[0] == "perception" and "retargeting" in stages and "/lomanip/to/optimize" in res.error_code.message
        assert len(res.keyframes.keyframes) > 0
        assert sim.poll() is None and perc.poll() is None and planner.poll() is None


def test_paper_model_file_without_weights_stops_the_node_with_one_line(tmp_path):
    """The paper's parameter file on a machine without the weights: exit 2 within seconds, one line
    naming the model and the parameter to set, no traceback."""
    import subprocess
    import sys
    import time

    from tests.graph.helpers import ROOT, graph_env

    env = {**graph_env(), "HF_HUB_CACHE": str(tmp_path / "hub")}
    paper = ROOT / "src/lomanip_perception/config/paper_models.yaml"
    t0 = time.monotonic()
    r = subprocess.run([sys.executable, "-m", "lomanip_perception.perception_node", "--ros-args", "-p",
                        f"config_file:={paper}"], env=env, capture_output=True, text=True, timeout=60)  # fmt: skip
    elapsed = time.monotonic() - t0
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert r.returncode == 2, r.stderr
    assert len(lines) == 1 and lines[0].startswith("lomanip_perception: error: FLUX.1 (image_generator)"), r.stderr
    assert "models.image_generator.params.path" in lines[0] and "Traceback" not in r.stderr
    assert elapsed < 30.0


def test_no_person_in_the_generated_image_is_named_and_the_node_keeps_serving(client, tmp_path):
    """A generator whose image shows no person (the synthetic generator with with_person: false):
    NO_HUMAN_FOUND naming the subtask, on every request, and the node stays up."""
    from lomanip_msgs.msg import ErrorCode
    from lomanip_msgs.srv import ExtractContacts

    sim_log, perc_log = tmp_path / "sim.log", tmp_path / "perception.log"
    overrides = '"{models: {image_generator: {params: {with_person: false, width: 256, height: 256}}}}"'  # a string
    with ros_process(["-m", "lomanip_sim.sim_node", "--ros-args", "-p", "scenario:=s1_basket",
                      "-p", "camera_rate:=2.0"], sim_log) as sim, \
            ros_process(["-m", "lomanip_perception.perception_node", "--ros-args", "-p",
                         f"config_overrides:={overrides}"], perc_log) as perc:  # fmt: skip
        cli = client.create_client(ExtractContacts, "/lomanip/perception/extract_contacts")
        wait_for(lambda: cli.service_is_ready(), 60, "extract_contacts service", proc=perc, log_path=perc_log)
        for _ in range(2):
            res = _call(client, cli, ExtractContacts.Request(prompts=["pick up the box", "grab the basket"]))
            assert res.error_code.val == ErrorCode.NO_HUMAN_FOUND, res.error_code.message
            assert res.error_code.message.startswith("subtask 0 'pick up the box': no person found")
        assert sim.poll() is None and perc.poll() is None
