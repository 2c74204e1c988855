"""The planner waits for a still robot: the speeds it judges that by."""
from __future__ import annotations

import numpy as np
import pytest


def _joints(v):
    from sensor_msgs.msg import JointState

    return JointState(name=[f"j{i}" for i in range(len(v))], position=[0.0] * len(v), velocity=list(v))


def test_pelvis_speed_needs_a_fifth_of_a_second_of_tf():
    from lomanip_planner.planner_node import _speeds

    track = [(0.0, np.zeros(3)), (0.1, np.array([0.001, 0.0, 0.0]))]
    base, joint = _speeds(track, _joints([0.01, -0.03]))
    assert base is None and joint == pytest.approx(0.03)


def test_pelvis_speed_over_the_last_fifth_of_a_second():
    from lomanip_planner.planner_node import _speeds

    # 2 cm/s forward, sampled at 50 Hz for 1 s, then still for the last 0.3 s
    track = [(0.02 * k, np.array([min(0.02 * k, 0.7) * 0.02, 0.0, 0.79])) for k in range(51)]
    base, _ = _speeds(track, _joints([0.0]))
    assert base == pytest.approx(0.0, abs=1e-9)
    track = [(0.02 * k, np.array([0.02 * 0.02 * k, 0.0, 0.79])) for k in range(51)]
    base, _ = _speeds(track, _joints([0.0]))
    assert base == pytest.approx(0.02, rel=1e-6)
