"""The `lomanip` command as a user runs it: bad input, a dying node, a recorded bag."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from .helpers import graph_env

pytestmark = pytest.mark.graph

LOMANIP = [sys.executable, "-m", "lomanip_launch.cli"]


def _run(args, cwd, timeout=120):
    return subprocess.run(LOMANIP + args, cwd=cwd, env=graph_env(), capture_output=True, text=True, timeout=timeout)


@pytest.mark.parametrize("args, message", [
    (["up", "--scenario", "s9_moon"], "unknown scenario 's9_moon'"),
    (["up", "--set", "box_mass=-2"], "box_mass"),
    (["up", "--set", "no_such_parameter=1"], "unknown parameter 'no_such_parameter'"),
])
def test_bad_input_is_one_clear_line(tmp_path, args, message):
    res = _run(args + ["--run-dir", str(tmp_path)], tmp_path)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("lomanip: error:") and message in lines[0], res.stderr


def test_malformed_parameter_file(tmp_path):
    bad = tmp_path / "params.yaml"
    bad.write_text("lomanip_sim:\n  ros__parameters:\n    scenario: [s1_basket\n")
    res = _run(["up", "--params", str(bad), "--run-dir", str(tmp_path)], tmp_path)
    assert res.returncode == 2 and "not valid YAML" in res.stderr and str(bad) in res.stderr


def _pids_of(pattern: str) -> list[int]:
    out = subprocess.run(["pgrep", "-f", pattern], capture_output=True, text=True).stdout.split()
    return [int(p) for p in out if int(p) != os.getpid()]


def _wait_for_images(count: int, timeout: float) -> None:
    import rclpy
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import Image

    rclpy.init()
    node = rclpy.create_node("orchestrator_test_watcher")
    got = []
    node.create_subscription(Image, "/lomanip/camera/rgb/image_raw", lambda m: got.append(1), qos_profile_sensor_data)
    try:
        deadline = time.monotonic() + timeout
        while len(got) < count:
            assert time.monotonic() < deadline, f"only {len(got)} images in {timeout} s"
            rclpy.spin_once(node, timeout_sec=0.1)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def _parent(pid: int) -> int:
    with open(f"/proc/{pid}/stat") as f:
        return int(f.read().rsplit(")", 1)[1].split()[1])


def test_killed_node_stops_the_graph_and_the_bag_is_readable(tmp_path):
    from rosbags.highlevel import AnyReader

    from lomanip_launch.bag import make_typestore, summarize_bag

    bag = tmp_path / "bag"
    proc = subprocess.Popen(LOMANIP + ["up", "--scenario", "s2_trolley", "--record", str(bag), "--run-dir", str(tmp_path)],
                            cwd=tmp_path, env=graph_env(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    output = []
    deadline = time.monotonic() + 120
    for line in proc.stdout:
        output.append(line)
        if "graph is up" in line:
            break
        assert time.monotonic() < deadline, "".join(output)
    _wait_for_images(count=20, timeout=90)   # slow machines take a while to open the GL context
    children = [p for p in _pids_of("lomanip_sim.sim_node") if _parent(p) == proc.pid]
    assert len(children) == 1, "".join(output)
    os.kill(children[0], signal.SIGKILL)
    rest, _ = proc.communicate(timeout=60)
    text = "".join(output) + rest
    assert proc.returncode == 3, text
    assert "node lomanip_sim exited with code -9" in text
    assert "lomanip_recorder" in text and "exited(0)" in text   # the recorder was stopped cleanly
    # The bag the recorder closed on shutdown is complete and every message deserialises.
    summary = summarize_bag(bag)
    counts = {t.topic: t.count for t in summary.topics}
    assert counts["/lomanip/scene_objects"] == 1 and counts["/joint_states"] > 100
    assert counts["/lomanip/camera/rgb/image_raw"] > 10
    n = 0
    with AnyReader([bag], default_typestore=make_typestore()) as reader:
        for conn, _, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)
            n += 1
    assert n == summary.message_count
    # No lomanip process of this graph is left behind.
    time.sleep(0.5)
    assert not [p for p in _pids_of("lomanip_launch.recorder_node") if str(bag) in open(f"/proc/{p}/cmdline").read()]


def test_ctrl_c_stops_everything_cleanly(tmp_path):
    shm_before = {f for f in os.listdir("/dev/shm") if f.startswith("fastrtps_")}
    proc = subprocess.Popen(LOMANIP + ["up", "--run-dir", str(tmp_path)], cwd=tmp_path, env=graph_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    output = []
    for line in proc.stdout:
        output.append(line)
        if "graph is up" in line:
            break
    children = [p for p in _pids_of("lomanip_sim.sim_node") if _parent(p) == proc.pid]
    assert children, "".join(output)
    proc.send_signal(signal.SIGINT)
    rest, _ = proc.communicate(timeout=60)
    text = "".join(output) + rest
    assert proc.returncode == 0, text
    assert "SIGINT received, stopping" in text and "exited(0)" in text
    time.sleep(0.3)
    assert not any(os.path.exists(f"/proc/{p}") and open(f"/proc/{p}/stat").read().split()[2] != "Z"
                   for p in children)
    shm_after = {f for f in os.listdir("/dev/shm") if f.startswith("fastrtps_")}
    assert shm_after <= shm_before | _shm_of_live_processes(), (shm_after - shm_before, text[-3000:])


def _shm_of_live_processes() -> set[str]:
    from lomanip_launch.process_graph import _shm_in_use

    return _shm_in_use()


def test_scenario_overrides_reach_the_sim(tmp_path):
    """Several --set values travel to the sim node as one YAML string parameter (a mapping given to
    rcl's -p parser unquoted makes it refuse to start). 8 s up: the graph counts as up once every node
    exists, and under load (a fresh clone beside a TO solve) the sim had not built the scenario 1 s later."""
    res = _run(["up", "--scenario", "s2_trolley", "--set", "box_mass=5.0", "--set", "box_yaw=0.6",
                "--duration", "8", "--run-dir", str(tmp_path)], tmp_path, timeout=180)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    sim_log = next(tmp_path.glob("*/logs/lomanip_sim.log")).read_text()
    assert "scenario s2_trolley ready" in sim_log


def test_a_second_graph_in_the_same_domain_is_refused(tmp_path):
    """A node named as one of ours already in this ROS_DOMAIN_ID (another `lomanip` running): one
    clear line and exit code 3, before any node is started."""
    fake = subprocess.Popen([sys.executable, "-c",
                             "import rclpy, time\nrclpy.init()\nn = rclpy.create_node('lomanip_planner')\n"
                             "while True:\n    rclpy.spin_once(n, timeout_sec=0.1)"],
                            env=graph_env(), start_new_session=True)
    try:
        time.sleep(2.0)
        assert fake.poll() is None
        res = _run(["up", "--run-dir", str(tmp_path)], tmp_path)
        assert res.returncode == 3, res.stdout + res.stderr
        assert "another lomanip graph is running" in res.stderr and "lomanip_planner" in res.stderr, res.stderr
        assert "started lomanip_sim" not in res.stdout + res.stderr
    finally:
        os.killpg(fake.pid, signal.SIGKILL)
        fake.wait(5)
