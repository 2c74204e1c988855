"""frames: quaternion order conversions and rotation helpers agree with each other and MuJoCo."""

import mujoco
import numpy as np
import pytest

from lomanip_sim import frames


def _random_quat(rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def test_order_round_trip():
    q = np.array([0.9, 0.1, -0.2, 0.3])
    q /= np.linalg.norm(q)
    ros = frames.mujoco_to_ros_quat(q)
    assert np.allclose(ros, [q[1], q[2], q[3], q[0]])
    assert np.allclose(frames.ros_to_mujoco_quat(ros), q)
    assert np.allclose(frames.pinocchio_to_mujoco_quat(frames.mujoco_to_pinocchio_quat(q)), q)


def test_matrix_matches_mujoco():
    rng = np.random.default_rng(0)
    for _ in range(50):
        q = _random_quat(rng)
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, q)
        assert np.allclose(frames.quat_to_matrix(q), R.reshape(3, 3))
        assert np.allclose(frames.matrix_to_quat(R.reshape(3, 3)), q)


def test_yaw_rpy_and_multiply():
    assert np.isclose(frames.quat_to_yaw(frames.yaw_to_quat(1.2)), 1.2)
    q = frames.rpy_to_quat(0.1, -0.2, 0.7)
    assert np.allclose(frames.quat_to_rpy(q), [0.1, -0.2, 0.7])
    a, b = frames.yaw_to_quat(0.3), frames.yaw_to_quat(0.4)
    assert np.allclose(frames.quat_multiply(a, b), frames.yaw_to_quat(0.7))
    assert np.isclose(frames.tilt_angle(frames.rpy_to_quat(0.3, 0, 1.0)), 0.3)


def test_qpos_conversion_pinocchio():
    qpos = np.arange(36, dtype=float)
    qpos[3:7] = [1, 0, 0, 0]
    q = frames.mujoco_qpos_to_pinocchio(qpos)
    assert np.allclose(q[3:7], [0, 0, 0, 1])
    assert np.allclose(frames.pinocchio_q_to_mujoco(q), qpos)


def test_look_at_camera_and_optical():
    eye, target = np.array([2.0, -1.0, 1.5]), np.array([0.0, 0.0, 0.5])
    R = frames.quat_to_matrix(frames.look_at_mujoco_camera_quat(eye, target))
    fwd = (target - eye) / np.linalg.norm(target - eye)
    assert np.allclose(-R[:, 2], fwd)
    _, R_opt = frames.mujoco_camera_to_optical(eye, R)
    assert np.allclose(R_opt[:, 2], fwd)  # optical z forward
    assert R_opt[2, 1] < 0  # optical y points down-ish in the world


def test_bad_inputs():
    with pytest.raises(frames.FrameError):
        frames.quat_to_matrix([0, 0, 0, 0])
    with pytest.raises(frames.FrameError):
        frames.wxyz_to_xyzw([1, 0, 0])
