"""Bag writing and summaries with rosbags, no ROS graph needed."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
import yaml

from lomanip_launch.bag import BagError, BagWriter, make_typestore, qos_for_bag, summarize_bag


def test_custom_types_register_with_the_installed_type_hash():
    store = make_typestore(["lomanip_msgs/msg/WholeBodyTrajectory"])
    installed = json.loads((Path(sys.prefix) / "share/lomanip_msgs/msg/WholeBodyTrajectory.json").read_text())
    expected = installed["type_hashes"][0]["hash_string"]
    assert store.hash_rihs01("lomanip_msgs/msg/WholeBodyTrajectory") == expected


def test_written_bag_reads_back_with_counts_and_jazzy_metadata(tmp_path):
    store = make_typestore(["lomanip_msgs/msg/SceneObjects"])
    Str = store.types["std_msgs/msg/String"]
    Scene = store.types["lomanip_msgs/msg/SceneObjects"]
    bag = tmp_path / "bag"
    writer = BagWriter(bag)
    writer.add_topic("/chatter", "std_msgs/msg/String", qos_for_bag(True, False))
    writer.add_topic("/lomanip/scene_objects", "lomanip_msgs/msg/SceneObjects", qos_for_bag(True, True))
    for i in range(25):
        writer.write("/chatter", 1_000_000_000 + i * 100_000_000, store.serialize_cdr(Str(data=f"m{i}"), Str.__msgtype__))
    header = store.types["std_msgs/msg/Header"](stamp=store.types["builtin_interfaces/msg/Time"](sec=1, nanosec=0), frame_id="world")
    scene = Scene(header=header, scenario="s1_basket", parameters_yaml="", objects=[])
    writer.write("/lomanip/scene_objects", 1_500_000_000, store.serialize_cdr(scene, Scene.__msgtype__))
    writer.close()

    summary = summarize_bag(bag)
    counts = {t.topic: t.count for t in summary.topics}
    assert counts == {"/chatter": 25, "/lomanip/scene_objects": 1}
    assert summary.storage == "mcap"
    assert summary.duration_s == pytest.approx(2.4, abs=1e-6)
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["version"] == 9 and meta["storage_identifier"] == "mcap"
    topics = {t["topic_metadata"]["name"]: t["topic_metadata"] for t in meta["topics_with_message_count"]}
    assert topics["/lomanip/scene_objects"]["type_description_hash"].startswith("RIHS01_")
    assert "transient_local" in str(topics["/lomanip/scene_objects"]["offered_qos_profiles"])


def test_existing_bag_folder_and_non_bag_are_refused(tmp_path):
    with pytest.raises(BagError, match="already exists"):
        BagWriter(tmp_path)
    with pytest.raises(BagError, match="not a rosbag2 bag"):
        summarize_bag(tmp_path)
