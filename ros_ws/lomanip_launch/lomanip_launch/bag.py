"""rosbag2 bags without ROS: write MCAP bags from serialized messages, and summarise bags.

`ros2 bag` is not installable from pip, so lomanip records with the `rosbags` library. Bags are
rosbag2 version 9 (Jazzy) with MCAP storage: `ros2 bag info/play`, Foxglove and `rosbags` read them.
Message types that the stock Jazzy typestore lacks (lomanip_msgs, ...) are registered from the
installed .msg files, so the bag carries their full definitions.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import yaml
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore


class BagError(RuntimeError):
    """A bag could not be written or read."""


_PRIMITIVES = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
               "int32", "uint32", "int64", "uint64", "string", "wstring", "time", "duration"}


def _msg_file(typename: str, share_dirs: list[Path]) -> Path:
    pkg, kind, name = typename.split("/")
    for share in share_dirs:
        candidate = share / pkg / kind / f"{name}.msg"
        if candidate.is_file():
            return candidate
    raise BagError(f"no definition of {typename} found under {', '.join(map(str, share_dirs))}")


def _dependencies(msg_text: str, own_package: str) -> set[str]:
    """Message types a .msg text references (constants are always primitive, so skipped)."""
    deps: set[str] = set()
    for raw in msg_text.splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line or line.startswith("---"):
            continue
        base = re.sub(r"(<=\d+)?(\[[^\]]*\])?$", "", line.split()[0])
        base = re.sub(r"<=\d+$", "", base)
        if base in _PRIMITIVES:
            continue
        if base == "Header":
            base = "std_msgs/Header"
        elif "/" not in base:
            base = f"{own_package}/{base}"
        parts = base.split("/")
        deps.add(f"{parts[0]}/msg/{parts[-1]}")
    return deps


def ament_share_dirs() -> list[Path]:
    """share/ folders of the ament prefixes in use (AMENT_PREFIX_PATH, else this venv)."""
    import os
    import sys

    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    prefixes.append(sys.prefix)
    return [Path(p) / "share" for p in prefixes]


def make_typestore(extra_types: list[str] = (), share_dirs: list[Path] | None = None) -> Typestore:
    """The Jazzy typestore plus the given types and everything they reference."""
    store = get_typestore(Stores.ROS2_JAZZY)
    dirs = share_dirs if share_dirs is not None else ament_share_dirs()
    pending = [t for t in extra_types if t not in store.fielddefs]
    found: dict[str, str] = {}
    while pending:
        typename = pending.pop()
        if typename in found or typename in store.fielddefs:
            continue
        text = _msg_file(typename, dirs).read_text(encoding="utf-8")
        found[typename] = text
        pending.extend(d for d in _dependencies(text, typename.split("/")[0])
                       if d not in found and d not in store.fielddefs)
    types = {}
    for typename, text in found.items():
        types.update(get_types_from_msg(text, typename))
    if types:
        store.register(types)
    return store


def qos_for_bag(reliable: bool, transient_local: bool, depth: int = 10) -> Qos:
    """The offered QoS profile recorded for a topic (what `ros2 bag play` will offer again)."""
    infinite = QosTime(2147483647, 4294967295)
    return Qos(QosHistory.KEEP_LAST, depth,
               QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
               QosDurability.TRANSIENT_LOCAL if transient_local else QosDurability.VOLATILE,
               infinite, infinite, QosLiveliness.AUTOMATIC, infinite, False)


class BagWriter:
    """Writes serialized (CDR) messages of any number of topics into one MCAP rosbag2 bag."""

    def __init__(self, path: Path, compress: bool = False) -> None:
        self.path = Path(path)
        if self.path.exists():
            raise BagError(f"bag folder {self.path} already exists; choose a new one")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        if compress:
            from rosbags.rosbag2 import CompressionFormat, CompressionMode
            self._writer.set_compression(CompressionMode.MESSAGE, CompressionFormat.ZSTD)
        self._writer.open()
        self._store = get_typestore(Stores.ROS2_JAZZY)
        self._connections: dict[str, object] = {}
        self.counts: dict[str, int] = {}
        self._closed = False

    def has_topic(self, topic: str) -> bool:
        return topic in self._connections

    def add_topic(self, topic: str, msgtype: str, qos: Qos, type_hash: str | None = None) -> None:
        """Register a topic; msgtype like "sensor_msgs/msg/Image"."""
        if msgtype not in self._store.fielddefs:
            self._store = make_typestore(list(self._store.fielddefs.keys() - get_typestore(
                Stores.ROS2_JAZZY).fielddefs.keys()) + [msgtype])
        self._connections[topic] = self._writer.add_connection(
            topic, msgtype, typestore=self._store, rihs01=type_hash,
            serialization_format="cdr", offered_qos_profiles=[qos])
        self.counts[topic] = 0

    def write(self, topic: str, stamp_ns: int, data: bytes) -> None:
        self._writer.write(self._connections[topic], stamp_ns, data)
        self.counts[topic] += 1

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._writer.close()


@dataclass
class TopicSummary:
    topic: str
    msgtype: str
    count: int
    frequency_hz: float


@dataclass
class BagSummary:
    path: Path
    storage: str
    duration_s: float
    start_ns: int
    end_ns: int
    message_count: int
    size_bytes: int
    topics: list[TopicSummary]

    def format(self) -> str:
        lines = [f"Bag:       {self.path}",
                 f"Storage:   {self.storage}   Size: {self.size_bytes / 1e6:.1f} MB",
                 f"Duration:  {self.duration_s:.2f} s   Messages: {self.message_count}",
                 f"{'Topic':<44} {'Type':<40} {'Count':>7} {'Hz':>7}"]
        for t in self.topics:
            lines.append(f"{t.topic:<44} {t.msgtype:<40} {t.count:>7} {t.frequency_hz:>7.1f}")
        return "\n".join(lines)


def summarize_bag(path: Path) -> BagSummary:
    """Read a rosbag2 bag's metadata and message index (no ROS needed)."""
    from rosbags.rosbag2 import Reader

    path = Path(path)
    if not (path / "metadata.yaml").is_file():
        raise BagError(f"{path} is not a rosbag2 bag (no metadata.yaml)")
    try:
        with Reader(path) as reader:
            duration = reader.duration / 1e9 if reader.message_count else 0.0
            topics = []
            for topic, info in sorted(reader.topics.items()):
                rate = (info.msgcount - 1) / duration if duration > 0 and info.msgcount > 1 else 0.0
                topics.append(TopicSummary(topic, info.msgtype or "?", info.msgcount, rate))
            meta = yaml.safe_load((path / "metadata.yaml").read_text(encoding="utf-8"))
            storage = meta["rosbag2_bagfile_information"].get("storage_identifier", "?")
            size = sum(f.stat().st_size for f in path.iterdir() if f.is_file())
            return BagSummary(path, str(storage), duration, reader.start_time, reader.end_time,
                              reader.message_count, size, topics)
    except BagError:
        raise
    except Exception as exc:  # rosbags raises several types for damaged bags
        raise BagError(f"cannot read bag {path}: {exc}") from exc
