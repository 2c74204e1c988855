"""The TO's self-collision spheres see the arm-against-hip contacts that MuJoCo's G1 meshes make."""
import mujoco
import numpy as np
import pytest

from lomanip_to.discretize import self_pairs


def _mujoco_qpos(g1, x):
    q = g1.x_to_q(x)  # Pinocchio: p, quat (x, y, z, w), joints
    return np.concatenate([q[:3], [q[6], q[3], q[4], q[5]], q[7:]])


def _wrist_hip_contacts(model, data, g1, x):
    data.qpos[:] = _mujoco_qpos(g1, x)
    mujoco.mj_forward(model, data)
    out = []
    for c in data.contact[:data.ncon]:
        names = {model.body(model.geom_bodyid[c.geom1]).name, model.body(model.geom_bodyid[c.geom2]).name}
        if any("right_wrist" in n for n in names) and any("right_hip" in n for n in names):
            out.append(c.dist)
    return out


def _closest_self_pair(g1, x, limbs=("right_hand", "right_wrist")):
    c = g1.numeric(x)["spheres"]
    best = np.inf
    for i, j in self_pairs(g1):
        if g1.spheres[i].name in limbs:
            d = np.linalg.norm(np.asarray(c[i]) - np.asarray(c[j])) - g1.spheres[i].radius - g1.spheres[j].radius
            best = min(best, d)
    return best


@pytest.mark.parametrize("roll", [0.15, 0.25, 0.35, 0.45])
def test_arm_swung_into_the_hip_is_a_self_collision_in_the_to(g1, roll):
    """Executed S1/S2 plans fell when the right wrist hit the hip links (the TO's pairs only had the
    hand against pelvis, torso and thigh spheres, which left 1-5 cm between them here)."""
    from lomanip_sim.robot_model import load_g1_model

    model = load_g1_model()
    data = mujoco.MjData(model)
    x = np.array(g1.x_stand(), float)
    j = 6 + list(g1.joint_names).index("right_shoulder_roll_joint")
    x[j] += roll
    assert _wrist_hip_contacts(model, data, g1, x), "MuJoCo reports no wrist/hip contact at this pose"
    assert _closest_self_pair(g1, x) < 0.0


def test_standing_pose_is_clear_of_every_self_pair(g1):
    x = np.array(g1.x_stand(), float)
    c = g1.numeric(x)["spheres"]
    for i, j in self_pairs(g1):
        d = np.linalg.norm(np.asarray(c[i]) - np.asarray(c[j])) - g1.spheres[i].radius - g1.spheres[j].radius
        assert d > 0.02, (g1.spheres[i].name, g1.spheres[j].name, d)
