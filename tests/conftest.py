"""Test-wide environment: DDS stays on this machine and each pytest run gets its own domain.

Set before any test module imports rclpy, so every in-process node and every child process the
tests start inherit it.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
# A domain of our own (0..232) so parallel test runs on one machine never see each other.
os.environ["ROS_DOMAIN_ID"] = os.environ.get("LOMANIP_TEST_DOMAIN_ID", str(1 + os.getpid() % 200))
os.environ.setdefault("FASTRTPS_DEFAULT_PROFILES_FILE", str(ROOT / "ros_ws/config/fastdds_localhost_shm.xml"))
os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYTHONUNBUFFERED", "1")

for pkg in ("src/lomanip_sim", "src/lomanip_to", "src/lomanip_perception", "src/lomanip_planner",
            "ros_ws/lomanip_launch"):
    path = str(ROOT / pkg)
    if path not in sys.path:
        sys.path.insert(0, path)


@pytest.fixture(autouse=True, scope="module")
def _no_stale_dds_shared_memory():
    """Each test module starts without stale Fast DDS shared-memory files.

    A node killed by a test (the orchestrator's kill tests do it on purpose) can leave its port
    file; the next participant given that port on our domain then hears nothing over shared memory,
    and every later graph test of the run failed (lomanip_launch.process_graph.remove_stale_shm).
    """
    from lomanip_launch.process_graph import remove_stale_shm

    remove_stale_shm(min_age=2.0)  # no participant of this run is starting now
    yield
