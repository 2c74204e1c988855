"""The symbolic G1 kinematics/centroidal terms agree with Pinocchio (1e-9)."""
import numpy as np
import pinocchio as pin

from lomanip_to.model import FEET, HAND_POINT, LIMBS, SOLE_CENTER


def _random_state(g1, rng):
    x = np.zeros(35)
    x[:3] = rng.uniform(-1, 1, 3)
    x[3:6] = rng.uniform(-0.8, 0.8, 3)
    x[6:] = rng.uniform(g1.q_lower, g1.q_upper)
    xd = rng.normal(size=35)
    return x, xd


def test_model_dimensions(g1):
    assert g1.nj == 29 and len(g1.joint_names) == 29
    assert abs(g1.mass - 33.34) < 0.01
    assert g1.joint_names[0] == "left_hip_pitch_joint" and g1.joint_names[-1] == "right_wrist_yaw_joint"
    assert g1.tau_max[g1.joint_names.index("left_knee_joint")] == 139.0
    x = g1.x_stand()
    assert np.allclose(g1.q_to_x(g1.x_to_q(x)), x)


def test_kinematics_and_cmm_match_pinocchio(g1):
    m, d = g1.pin_model, g1.pin_model.createData()
    f = g1.casadi_functions
    rng = np.random.default_rng(0)
    for _ in range(3):
        x, xd = _random_state(g1, rng)
        q, v = g1.x_to_q(x), g1.xd_to_v(x, xd)
        assert np.allclose(g1.v_to_xd(x, v), xd, atol=1e-10)
        pin.forwardKinematics(m, d, q, v)
        # limb points
        pts = np.array(f["limbs"](x))
        for i, limb in enumerate(("left_foot", "right_foot", "left_hand", "right_hand")):
            local = SOLE_CENTER if limb in FEET else HAND_POINT[limb]
            ref = d.oMi[g1.limb_joint[limb]].act(local)
            assert np.allclose(pts[:, i], ref, atol=1e-9)
        # CoM
        com_ref = pin.centerOfMass(m, d, q)
        assert np.allclose(np.array(f["com"](x)).ravel(), com_ref, atol=1e-9)
        # centroidal momentum and matrix
        Ag = pin.ccrba(m, d, q, v)
        h_ref = Ag @ v
        assert np.allclose(np.array(f["h"](x, xd)).ravel(), h_ref, atol=1e-9)
        # CMM in TO coordinates = Ag @ dv/dxd
        T = np.zeros((35, 35))
        for k in range(35):
            e = np.zeros(35)
            e[k] = 1.0
            T[:, k] = g1.xd_to_v(x, e)
        assert np.allclose(np.array(f["cmm"](x)), Ag @ T, atol=1e-9)
        # numpy path equals casadi path
        num = g1.numeric(x, xd)
        assert np.allclose(num["h"], h_ref, atol=1e-9)


def test_quasi_static_limb_torques_match_rnea_at_rest(g1):
    """The TO's limb and waist torque rows equal Pinocchio's RNEA at zero velocity and acceleration."""
    m, d = g1.pin_model, g1.pin_model.createData()
    rng = np.random.default_rng(1)
    names = {limb: [m.names[j] for j in js] for limb, js in g1.limb_torque_joints.items()}
    assert names["left_foot"][0] == "left_hip_pitch_joint" and names["left_foot"][-1] == "left_ankle_roll_joint"
    assert names["right_hand"][0] == "right_shoulder_pitch_joint"
    assert names["right_hand"][-1] == "right_wrist_yaw_joint" and len(names["right_hand"]) == 7
    for _ in range(3):
        x, _ = _random_state(g1, rng)
        q = g1.x_to_q(x)
        pin.forwardKinematics(m, d, q)
        tree = g1.symbolic_tree(x)
        frames = g1.limb_frames(tree)
        wrenches, fext = {}, [pin.Force.Zero() for _ in range(m.njoints)]
        for limb, (pt, _) in frames.items():
            f, moment = rng.normal(scale=40, size=3), rng.normal(scale=3, size=3)
            wrenches[limb] = ([(pt, f)], moment)
            o = d.oMi[g1.limb_joint[limb]]
            fext[g1.limb_joint[limb]] = pin.Force(o.rotation.T @ f,
                                                 o.rotation.T @ (moment + np.cross(pt - o.translation, f)))
        tau = pin.rnea(m, d, q, np.zeros(35), np.zeros(35), fext)
        ours = g1.quasi_static_limb_torques(tree, wrenches)
        assert set(ours) == set(LIMBS) | {"waist"}
        for group, (js, _) in g1.torque_row_joints.items():
            assert np.allclose(ours[group], [tau[6 + j - 2] for j in js], atol=1e-9)


def test_waist_rows_with_inertia_match_rnea_in_motion(g1):
    """Quasi-static joint torques plus the finite-difference inertial term equal Pinocchio's RNEA
    of the moving robot, for every joint group of the torque rows."""
    rng = np.random.default_rng(2)
    dt = 1e-6
    waist = g1.torque_row_joints["waist"][0]
    for _ in range(3):
        x, xd = _random_state(g1, rng)
        xdd = rng.normal(scale=5.0, size=35)
        xd_b = xd + dt * xdd
        x_b = x + dt * xd_b
        tree_a, tree_b = g1.symbolic_tree(x, xd), g1.symbolic_tree(x_b, xd_b)
        groups = tuple(g1.torque_row_joints)
        static = g1.quasi_static_limb_torques(tree_a, {})
        inertial = g1.inertial_torques(tree_a, tree_b, dt, groups)
        tau, _ = g1.rnea_torques(x, xd, xdd, {})
        for group in groups:
            js = g1.torque_row_joints[group][0]
            ours = np.array(static[group]) + np.array(inertial[group])
            # the model's rotor armature (0.01 kg m^2, a term the rows leave out)
            ref = np.array([tau[j - 2] - g1.pin_model.armature[6 + j - 2] * xdd[6 + j - 2] for j in js])
            assert np.allclose(ours, ref, atol=1e-3 * max(1.0, np.abs(ref).max())), (group, ours, ref)
        # and the inertial term is not negligible in such a motion
        ref = np.array([tau[j - 2] for j in waist])
        assert np.abs(ref - np.array(static["waist"])).max() > 0.5


def test_shin_spheres_cover_the_shin_from_the_knee_without_gaps(g1):
    """Crossing knees must show as a self-collision: the spheres overlap along the shin."""
    from lomanip_to.discretize import self_pairs

    names = [s.name for s in g1.spheres]
    cs = g1.numeric(np.zeros(35))["spheres"]
    for side in ("left", "right"):
        shin = [i for i, n in enumerate(names) if n.startswith(f"{side}_shin_")]
        assert len(shin) >= 3
        for a, b in zip(shin, shin[1:]):
            gap = np.linalg.norm(cs[a] - cs[b])
            assert gap < 2.0 * g1.spheres[a].radius + 0.025   # at most 2.5 cm between sphere surfaces
    pairs = {(names[i], names[j]) for i, j in self_pairs(g1)}
    assert ("left_shin_0", "right_shin_0") in pairs and ("left_shin_1", "right_shin_2") in pairs
