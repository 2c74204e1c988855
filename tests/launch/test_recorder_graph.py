"""The recorder as a real process over DDS: every published message ends up in the bag."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest
import yaml

pytestmark = pytest.mark.graph

N_MESSAGES = 60


def test_recorder_bag_matches_what_was_published(tmp_path):
    import rclpy
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    from lomanip_launch.bag import summarize_bag
    from lomanip_msgs.msg import SceneObjects

    bag = tmp_path / "bag"
    recorder = subprocess.Popen([sys.executable, "-m", "lomanip_launch.recorder_node", str(bag)],
                                env=dict(os.environ), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    rclpy.init()
    node = rclpy.create_node("test_publisher")
    try:
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        scene_pub = node.create_publisher(SceneObjects, "/lomanip/scene_objects", latched)
        scene_pub.publish(SceneObjects(scenario="s1_basket"))
        chatter = node.create_publisher(String, "/lomanip/test_chatter", QoSProfile(depth=100))
        ignored = node.create_publisher(String, "/not_lomanip", 10)
        deadline = time.monotonic() + 30
        while chatter.get_subscription_count() == 0 or scene_pub.get_subscription_count() == 0:
            assert time.monotonic() < deadline, "recorder never subscribed"
            assert recorder.poll() is None, recorder.stdout.read()
            rclpy.spin_once(node, timeout_sec=0.1)
        for i in range(N_MESSAGES):
            chatter.publish(String(data=f"message {i}"))
            ignored.publish(String(data="x"))
            time.sleep(0.005)
        time.sleep(1.0)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        recorder.send_signal(signal.SIGINT)
        out, _ = recorder.communicate(timeout=20)
    assert recorder.returncode == 0, out
    summary = summarize_bag(bag)
    counts = {t.topic: t.count for t in summary.topics}
    assert counts["/lomanip/test_chatter"] == N_MESSAGES
    assert counts["/lomanip/scene_objects"] == 1
    assert "/not_lomanip" not in counts
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    types = {t["topic_metadata"]["name"]: t["topic_metadata"] for t in meta["topics_with_message_count"]}
    assert types["/lomanip/scene_objects"]["type"] == "lomanip_msgs/msg/SceneObjects"
    # Hash the live graph advertised == hash rosbags computes from the .msg definition.
    from lomanip_launch.bag import make_typestore
    assert types["/lomanip/scene_objects"]["type_description_hash"] == \
        make_typestore(["lomanip_msgs/msg/SceneObjects"]).hash_rihs01("lomanip_msgs/msg/SceneObjects")
