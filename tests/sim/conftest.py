"""Shared setup for the lomanip_sim core tests (no ROS): import path and the 'slow' marker."""

import os
import sys
from pathlib import Path

_PKG = Path(__file__).resolve().parents[2] / "src" / "lomanip_sim"
if str(_PKG) not in sys.path:
    sys.path.insert(0, str(_PKG))

import lomanip_sim  # noqa: E402,F401  (selects MUJOCO_GL before mujoco is imported)

os.environ.setdefault("MUJOCO_GL", "egl")


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: takes more than ~20 s of wall time")
