"""A rosbag2 recorder node: subscribes (raw) to every lomanip topic as it appears and writes MCAP.

Topics are discovered from the graph every half second; the subscription QoS copies the
publishers' (best effort for camera streams, transient local for latched topics) so nothing is
refused. Action feedback/status topics are not recorded (their types have no .msg file); the plan
result itself is on /lomanip/trajectory.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from lomanip_launch.bag import BagError, BagWriter, qos_for_bag
from lomanip_launch.ros_types import message_class

DEFAULT_TOPICS = ("/lomanip/", "/joint_states", "/tf", "/tf_static", "/diagnostics")


def _matches(topic: str, patterns: tuple[str, ...]) -> bool:
    return any(topic == p or (p.endswith("/") and topic.startswith(p)) for p in patterns)


def should_record(topic: str, patterns: tuple[str, ...], exclude: tuple[str, ...] = ()) -> bool:
    """Exact names, or whole namespaces for patterns ending in '/'; never action internals."""
    if "/_action/" in topic or _matches(topic, exclude):
        return False
    return _matches(topic, patterns)


class RecorderNode(Node):
    def __init__(self, bag_path: Path, topics: tuple[str, ...], compress: bool, exclude: tuple[str, ...] = ()) -> None:
        super().__init__("lomanip_recorder")
        self.topics = topics
        self.exclude = exclude
        self.writer = BagWriter(bag_path, compress=compress)
        self._subs = []
        self.create_timer(0.5, self.discover)
        self.discover()
        skipped = f" except {', '.join(exclude)}" if exclude else ""
        self.get_logger().info(f"recording {', '.join(topics)}{skipped} to {bag_path}")

    def discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if self.writer.has_topic(topic) or not should_record(topic, self.topics, self.exclude):
                continue
            publishers = self.get_publishers_info_by_topic(topic)
            if not publishers:
                continue
            typename = types[0]
            try:
                cls = message_class(typename)
            except LookupError as exc:
                self.get_logger().warning(f"not recording {topic}: {exc}")
                self.writer.counts.setdefault(topic, 0)
                continue
            reliable = all(p.qos_profile.reliability == ReliabilityPolicy.RELIABLE for p in publishers)
            latched = any(p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in publishers)
            type_hash = str(publishers[0].topic_type_hash)
            try:
                self.writer.add_topic(topic, typename, qos_for_bag(reliable, latched),
                                      type_hash if type_hash.startswith("RIHS01_") else None)
            except BagError as exc:
                self.get_logger().warning(f"not recording {topic}: {exc}")
                continue
            qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                             reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)
            self._subs.append(self.create_subscription(
                cls, topic, lambda data, t=topic: self._on_message(t, data), qos, raw=True))
            self.get_logger().info(f"recording {topic} [{typename}]")

    def _on_message(self, topic: str, data: bytes) -> None:
        self.writer.write(topic, self.get_clock().now().nanoseconds, data)

    def close(self) -> str:
        self.writer.close()
        total = sum(self.writer.counts.values())
        return f"recorded {total} messages on {len(self.writer.counts)} topics to {self.writer.path}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Record lomanip topics to a rosbag2 (MCAP) bag.")
    parser.add_argument("bag", type=Path, help="output bag folder (must not exist)")
    parser.add_argument("--topics", nargs="*", default=list(DEFAULT_TOPICS),
                        help="topic names; a trailing '/' records the whole namespace")
    parser.add_argument("--exclude", nargs="*", default=[],
                        help="topic names or namespaces (trailing '/') not to record, e.g. /lomanip/camera/")
    parser.add_argument("--compress", action="store_true", help="zstd-compress messages")
    args, ros_args = parser.parse_known_args(argv)
    rclpy.init(args=ros_args)
    node = None
    try:
        node = RecorderNode(args.bag, tuple(args.topics), args.compress, tuple(args.exclude))
        rclpy.spin(node)
    except BagError as exc:
        print(f"lomanip_recorder: {exc}", file=sys.stderr)
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            print(node.close(), flush=True)
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
