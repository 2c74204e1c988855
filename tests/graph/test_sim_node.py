"""The simulation node as a real process: camera rates, state topics, services, bad input."""
from __future__ import annotations

import time

import numpy as np
import pytest

from .helpers import call_idempotent, ros_process, wait_for

pytestmark = pytest.mark.graph


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    log = tmp_path_factory.mktemp("sim") / "sim.log"
    with ros_process(["-m", "lomanip_sim.sim_node", "--ros-args", "-p", "scenario:=s2_trolley",
                      "-p", "camera_rate:=15.0"], log) as proc:
        yield proc, log


@pytest.fixture(scope="module")
def client_node():
    import rclpy

    rclpy.init()
    node = rclpy.create_node("sim_test_client")
    yield node
    node.destroy_node()
    rclpy.try_shutdown()


def _spin(node):
    import rclpy

    return lambda: rclpy.spin_once(node, timeout_sec=0.05)


def test_streams_from_another_process(sim, client_node):
    """RGB, depth and camera_info arrive in a separate process while physics runs paced."""
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import CameraInfo, Image, JointState

    proc, log = sim
    stamps: dict[str, list[float]] = {"rgb": [], "depth": [], "info": [], "joints": []}
    last: dict[str, object] = {}
    rtf: list[float] = []

    def keep(key):
        def cb(msg):
            stamps[key].append(time.monotonic())
            last[key] = msg
        return cb

    def on_diag(msg):
        for status in msg.status:
            for kv in status.values:
                if kv.key == "real_time_factor":
                    rtf.append(float(kv.value))

    subs = [client_node.create_subscription(Image, "/lomanip/camera/rgb/image_raw", keep("rgb"), qos_profile_sensor_data),
            client_node.create_subscription(Image, "/lomanip/camera/depth/image_raw", keep("depth"), qos_profile_sensor_data),
            client_node.create_subscription(CameraInfo, "/lomanip/camera/rgb/camera_info", keep("info"), qos_profile_sensor_data),
            client_node.create_subscription(JointState, "/joint_states", keep("joints"), 10),
            client_node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 10)]
    wait_for(lambda: len(stamps["rgb"]) >= 3 and len(stamps["depth"]) >= 3, 90, "first camera frames",
             spin=_spin(client_node), proc=proc, log_path=log)
    for k in stamps:
        stamps[k].clear()
    rtf.clear()
    t0 = time.monotonic()
    while time.monotonic() - t0 < 6.0:
        _spin(client_node)()
    window = time.monotonic() - t0
    rates = {k: len(v) / window for k, v in stamps.items()}
    print(f"\nrates over {window:.1f} s: " + ", ".join(f"{k} {r:.1f} Hz" for k, r in rates.items())
          + f"; real-time factor reports {rtf}")
    for s in subs:
        client_node.destroy_subscription(s)
    # Functional floor only: the >= 10 Hz target is measured by tools/bench_graph.py (`make bench`),
    # since a timed assertion here would fail on a loaded CI machine.
    assert rates["rgb"] >= 3 and rates["depth"] >= 3, rates
    assert rates["joints"] >= 20, rates
    assert rtf and sorted(rtf)[len(rtf) // 2] >= 0.8, rtf   # median; the first window includes start-up

    rgb, depth, info, joints = last["rgb"], last["depth"], last["info"], last["joints"]
    assert (rgb.encoding, rgb.width, rgb.height) == ("rgb8", 640, 480)
    assert (depth.encoding, depth.width, depth.height) == ("32FC1", 640, 480)
    d = np.frombuffer(depth.data, np.float32)
    finite = d[np.isfinite(d)]
    assert 0.3 < finite.min() < 6.0 and finite.max() < 500.0  # metres (the floor plane reaches far)
    k = np.array(info.k).reshape(3, 3)
    assert k[0, 2] == pytest.approx(319.5, abs=1.0) and k[0, 0] > 0 and info.distortion_model == "plumb_bob"
    assert len(joints.name) == 29 and joints.name[0] == "left_hip_pitch_joint"
    assert rgb.header.frame_id == info.header.frame_id == depth.header.frame_id


def test_scene_objects_are_latched(sim, client_node):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from lomanip_msgs.msg import SceneObjects

    proc, log = sim
    got = []
    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    sub = client_node.create_subscription(SceneObjects, "/lomanip/scene_objects", got.append, qos)
    wait_for(lambda: got, 60, "latched scene objects", spin=_spin(client_node), proc=proc, log_path=log)
    client_node.destroy_subscription(sub)
    scene = got[-1]
    assert scene.scenario == "s2_trolley"
    ids = {o.id: o for o in scene.objects}
    assert {"box", "table", "trolley"} <= set(ids)
    assert ids["box"].inertia.m == pytest.approx(2.5) and ids["box"].movable
    assert not ids["table"].movable and ids["box"].primitives


def _call(node, cli, request, timeout=60.0):
    """Snapshots and resets may be repeated, so a lost first response is re-sent (call_idempotent)."""
    return call_idempotent(node, cli, request, timeout=timeout, attempt=20.0)


def test_snapshot_service(sim, client_node):
    from lomanip_msgs.msg import ErrorCode
    from lomanip_msgs.srv import GetRGBDFrame

    cli = client_node.create_client(GetRGBDFrame, "/lomanip/sim/get_rgbd_frame")
    res = _call(client_node, cli, GetRGBDFrame.Request())
    assert res.error_code.val == ErrorCode.SUCCESS, res.error_code.message
    assert res.rgb.width == 640 and res.depth.encoding == "32FC1"
    assert res.camera_pose.header.frame_id == "world"
    assert res.camera_info.header.frame_id == res.rgb.header.frame_id


def test_reset_rejects_bad_input_and_accepts_new_parameters(sim, client_node):
    from lomanip_msgs.msg import ErrorCode, ScenarioParameters
    from lomanip_msgs.srv import ResetScenario

    proc, _ = sim
    cli = client_node.create_client(ResetScenario, "/lomanip/sim/reset")
    res = _call(client_node, cli, ResetScenario.Request(scenario=ScenarioParameters(name="s9_moon")))
    assert res.error_code.val == ErrorCode.UNKNOWN_SCENARIO and "s1_basket" in res.error_code.message
    res = _call(client_node, cli, ResetScenario.Request(
        scenario=ScenarioParameters(name="s1_basket", overrides_yaml="{box_mass: -1.0}")))
    assert res.error_code.val == ErrorCode.INVALID_REQUEST and "box_mass" in res.error_code.message
    res = _call(client_node, cli, ResetScenario.Request(
        scenario=ScenarioParameters(name="s1_basket", overrides_yaml="{box_mass: 5.0, box_yaw: 0.6}")))
    assert res.error_code.val == ErrorCode.SUCCESS, res.error_code.message
    box = next(o for o in res.scene.objects if o.id == "box")
    assert box.inertia.m == pytest.approx(5.0)
    assert res.scene.scenario == "s1_basket"
    # the same reset gives the same scene, bit for bit: the objects as placed, not a snapshot taken
    # after some physics steps (which made plans of the same task differ from run to run)
    time.sleep(0.5)
    again = _call(client_node, cli, ResetScenario.Request(
        scenario=ScenarioParameters(name="s1_basket", overrides_yaml="{box_mass: 5.0, box_yaw: 0.6}")))
    def poses(scene):
        return [(o.id, o.pose.position.x, o.pose.position.y, o.pose.position.z, o.pose.orientation.w,
                 o.pose.orientation.z) for o in scene.objects]
    assert poses(again.scene) == poses(res.scene)
    assert proc.poll() is None
