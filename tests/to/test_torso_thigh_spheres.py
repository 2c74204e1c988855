"""Deep squats: wherever MuJoCo's meshes put a thigh into the torso, the TO's spheres collide too."""
import itertools

import mujoco
import numpy as np

from lomanip_sim.robot_model import load_g1_model
from lomanip_to.discretize import self_pairs
from lomanip_to.model import rpy_to_rot


def _qpos(m, x):
    q = np.zeros(m.nq)
    q[:3] = x[:3]
    mujoco.mju_mat2Quat(q[3:7], rpy_to_rot(x[3:6]).ravel())
    q[7:36] = x[6:]
    return q


def _mesh_torso_thigh_depth(m, d, x) -> float:
    d.qpos[:] = _qpos(m, x)
    mujoco.mj_forward(m, d)
    torso = m.body("torso_link").id
    thigh = {m.body(f"{s}_{b}_link").id for s in ("left", "right") for b in ("hip_roll", "hip_yaw")}
    depth = 0.0
    for c in d.contact[:d.ncon]:
        bodies = {int(m.geom_bodyid[c.geom1]), int(m.geom_bodyid[c.geom2])}
        if torso in bodies and bodies & thigh:
            depth = max(depth, -c.dist)
    return depth


def test_torso_thigh_pairs_cover_the_meshes_in_squats(g1):
    m = load_g1_model()
    d = mujoco.MjData(m)
    names = [s.name for s in g1.spheres]
    pairs = [(i, j) for i, j in self_pairs(g1) if names[j].startswith("torso_low")]
    assert len(pairs) == 8
    names_j = list(g1.pin_model.names[2:])
    touching = 0
    false_overlap = 0.0
    sweep = itertools.product(np.arange(-1.9, -2.55, -0.05), (0.0, 0.3, 0.52), (-0.3, 0.0, 0.2), (-0.5, 0.0, 0.5))
    for hip, waist, roll, yaw in sweep:
        x = np.zeros(35)
        x[2] = 1.0  # in the air: only self-contacts count
        for s, sign in (("left", 1.0), ("right", -1.0)):
            x[6 + names_j.index(f"{s}_hip_pitch_joint")] = hip
            x[6 + names_j.index(f"{s}_knee_joint")] = 2.0
            x[6 + names_j.index(f"{s}_hip_roll_joint")] = sign * roll
            x[6 + names_j.index(f"{s}_hip_yaw_joint")] = sign * yaw
        x[6 + names_j.index("waist_pitch_joint")] = waist
        depth = _mesh_torso_thigh_depth(m, d, x)
        cs = g1.numeric(x)["spheres"]
        gap = min(np.linalg.norm(cs[i] - cs[j]) - g1.spheres[i].radius - g1.spheres[j].radius for i, j in pairs)
        if depth > 0.002:
            touching += 1
            assert gap < 0.0, (hip, waist, roll, yaw, depth, gap)
        elif depth == 0.0:
            false_overlap = max(false_overlap, -gap)
    assert touching > 50  # the sweep does reach the meshes' contact
    assert false_overlap < 0.02  # and the spheres are not much more conservative than the meshes
