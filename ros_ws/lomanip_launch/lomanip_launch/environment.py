"""Default environment for every process lomanip starts.

DDS must stay on this machine unless the user opts in (ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET), and
camera images need a shared-memory segment larger than Fast DDS's 512 kB default.
"""
from __future__ import annotations

import os
from pathlib import Path

_PACKAGE_DIR = Path(__file__).resolve().parent


def workspace_dir() -> Path:
    """The ros_ws/ folder of the checkout (config files live there)."""
    return _PACKAGE_DIR.parent.parent


def config_dir() -> Path:
    return workspace_dir() / "config"


def fastdds_profile() -> Path:
    return config_dir() / "fastdds_localhost_shm.xml"


def default_params_file() -> Path:
    return config_dir() / "lomanip.yaml"


def lomanip_environment(base: dict[str, str] | None = None) -> dict[str, str]:
    """The environment child processes get: the caller's, plus lomanip's safe defaults.

    Values the user already set win, so a multi-machine deployment can export
    ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET and its own DDS profile.
    """
    env = dict(os.environ if base is None else base)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    env.setdefault("FASTRTPS_DEFAULT_PROFILES_FILE", str(fastdds_profile()))
    env.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    env.setdefault("MUJOCO_GL", "egl")
    env.setdefault("PYTHONUNBUFFERED", "1")
    # Coloured, timestamped, node-named log lines from every process.
    env.setdefault("RCUTILS_CONSOLE_OUTPUT_FORMAT", "[{severity}] [{time}] [{name}]: {message}")
    return env


def apply_to_current_process() -> None:
    """Set the same defaults in this process (before rclpy.init)."""
    for key, value in lomanip_environment().items():
        os.environ.setdefault(key, value)
