"""robot_model: the G1 file is found via importlib and matches the constants lomanip relies on."""

import mujoco
import numpy as np

from lomanip_sim import robot_model as rm


def test_model_path_and_consistency():
    path = rm.g1_mjcf_path()
    assert path.is_file() and path.name == "g1.xml"
    assert "site-packages" in str(path) or "dist-packages" in str(path)
    facts = rm.check_model_consistency()
    assert (facts.nq, facts.nv, facts.nu) == (36, 35, 29)
    assert facts.timestep <= 0.002
    assert facts.torque_limits == rm.G1_TORQUE_LIMITS
    assert abs(facts.stand_qpos[2] - 0.79) < 1e-9


def test_torque_limit_table():
    lim = rm.G1_TORQUE_LIMITS
    assert lim["left_hip_pitch_joint"] == 88 and lim["right_hip_yaw_joint"] == 88
    assert lim["left_hip_roll_joint"] == 139 and lim["right_knee_joint"] == 139
    assert lim["left_ankle_pitch_joint"] == 50 and lim["waist_roll_joint"] == 50
    assert lim["waist_yaw_joint"] == 88 and lim["left_elbow_joint"] == 25
    assert lim["right_wrist_roll_joint"] == 25 and lim["right_wrist_yaw_joint"] == 5
    assert len(rm.G1_JOINT_NAMES) == 29 and rm.G1_TORQUE_LIMIT_VECTOR.shape == (29,)


def test_hand_bodies_exist():
    m = rm.load_g1_model()
    for b in list(rm.HAND_BODIES.values()) + list(rm.FOOT_BODIES.values()):
        assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, b) >= 0


def test_reach_search_is_sane():
    r = rm.hand_reach(samples=800, refine_iters=400)
    assert 1.4 < r.max_height < 1.75  # overhead reach of a 1.32 m robot with straight legs
    near = rm.hand_reach(target=np.array([0.35, 0.2, 0.9]), samples=800, refine_iters=400)
    assert near.distance < 0.03


def test_same_file_loads_in_pinocchio():
    import pytest

    pin = pytest.importorskip("pinocchio")
    m = pin.buildModelFromMJCF(str(rm.g1_mjcf_path()))
    assert (m.nq, m.nv) == (36, 35)
    assert tuple(m.names)[2:] == rm.G1_JOINT_NAMES
