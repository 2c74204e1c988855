"""Retargeting IK: contacts reached within 1 cm, feet flat, limits and self-collision held."""
from __future__ import annotations

import numpy as np
import pytest

from lomanip_planner.retargeting import (INVALID_REQUEST, RETARGETING_INFEASIBLE, LimbTarget, RetargetTarget,
                                         Retargeter, RetargetingError)
from lomanip_sim import frames
from lomanip_sim.robot_model import G1_JOINT_NAMES

LIMBS = ("left_foot", "right_foot", "left_hand", "right_hand")


@pytest.fixture(scope="module")
def retargeter():
    return Retargeter()


def _targets_from_pose(r: Retargeter, q: np.ndarray) -> tuple[LimbTarget, ...]:
    """Contact targets that a known configuration meets (so a solution exists)."""
    import mujoco

    d = mujoco.MjData(r.model)
    d.qpos[:] = q
    mujoco.mj_kinematics(r.model, d)
    q[2] -= min(d.site("left_foot").xpos[2], d.site("right_foot").xpos[2]) - r.sole_offset
    d.qpos[:] = q
    mujoco.mj_kinematics(r.model, d)
    return tuple(LimbTarget(l, d.site(l).xpos.copy() - (np.array([0, 0, r.sole_offset]) if "foot" in l else 0.0))
                 for l in LIMBS)


def _squat_reach(r: Retargeter, rng) -> np.ndarray:
    q = r.stand.copy()
    s = rng.uniform(0.1, 0.6)
    for side in ("left", "right"):
        for name, v in ((f"{side}_hip_pitch_joint", -s), (f"{side}_knee_joint", 2 * s), (f"{side}_ankle_pitch_joint", -s),
                        (f"{side}_shoulder_pitch_joint", -rng.uniform(0.2, 1.3)), (f"{side}_elbow_joint", rng.uniform(0.0, 1.2))):
            q[7 + G1_JOINT_NAMES.index(name)] = v
    q[3:7] = frames.yaw_to_quat(rng.uniform(-np.pi, np.pi))
    q[:2] = rng.uniform(-2, 2, size=2)
    return q


def test_reachable_contacts_are_met_within_a_centimetre(retargeter):
    rng = np.random.default_rng(7)
    times = []
    for _ in range(12):
        q_true = _squat_reach(retargeter, rng)
        targets = _targets_from_pose(retargeter, q_true)
        res = retargeter.solve(RetargetTarget(targets, base_orientation_wxyz=q_true[3:7]))
        times.append(res.seconds)
        assert max(res.residuals.values()) <= 0.01
        assert max(res.foot_tilt.values()) < np.deg2rad(2.0)          # feet flat in stance
        assert res.within_joint_limits and res.min_self_distance > 0.0
    # the time per keyframe is printed here and measured in tools/bench_plan.py, not asserted: a
    # timed assertion failed under load (two solves beside the test on 2 cores)
    print(f"\nretargeting time per keyframe: median {np.median(times) * 1e3:.1f} ms, max {max(times) * 1e3:.1f} ms")


def test_feet_on_a_raised_surface_with_yaw(retargeter):
    yaw = 0.6
    R = frames.quat_to_matrix(frames.yaw_to_quat(yaw))
    feet = [LimbTarget(f, np.array([1.0, 0.5, 0.30]) + R @ np.array([0.0, s * 0.11, 0.0]), object_id="box")
            for f, s in (("left_foot", 1), ("right_foot", -1))]
    res = retargeter.solve(RetargetTarget(tuple(feet), base_orientation_wxyz=frames.yaw_to_quat(yaw)))
    assert max(res.residuals.values()) <= 0.01
    assert frames.quat_to_yaw(res.base_quat_wxyz) == pytest.approx(yaw, abs=0.05)
    assert res.base_position[2] > 0.30 + 0.6


def test_joint_prior_shapes_the_free_limbs(retargeter):
    feet = (LimbTarget("left_foot", np.array([0.0, 0.12, 0.0])), LimbTarget("right_foot", np.array([0.0, -0.12, 0.0])))
    res = retargeter.solve(RetargetTarget(feet, joint_prior={"left_elbow_joint": 1.4, "right_shoulder_pitch_joint": -1.0}))
    assert res.joints["left_elbow_joint"] == pytest.approx(1.4, abs=0.05)
    assert res.joints["right_shoulder_pitch_joint"] == pytest.approx(-1.0, abs=0.05)


def test_unreachable_contact_names_the_limb(retargeter):
    targets = (LimbTarget("left_foot", np.array([0.0, 0.12, 0.0])), LimbTarget("right_foot", np.array([0.0, -0.12, 0.0])),
               LimbTarget("left_hand", np.array([0.3, 0.2, 2.2]), object_id="basket"))
    with pytest.raises(RetargetingError) as err:
        retargeter.solve(RetargetTarget(targets))
    assert err.value.code == RETARGETING_INFEASIBLE and "left_hand" in str(err.value) and "basket" in str(err.value)


@pytest.mark.parametrize("target, message", [
    (RetargetTarget((LimbTarget("left_foot", np.array([0.0, np.nan, 0.0])),)), "finite"),
    (RetargetTarget((LimbTarget("left_hand", np.array([0.3, 0.2, 1.0])),)), "at least one foot"),
    (RetargetTarget((LimbTarget("tail", np.zeros(3)),)), "unknown limb"),
    (RetargetTarget((LimbTarget("left_foot", np.zeros(3)),), joint_prior={"panda_joint1": 0.1}), "panda_joint1"),
])
def test_bad_input(retargeter, target, message):
    with pytest.raises(RetargetingError) as err:
        retargeter.solve(target)
    assert err.value.code == INVALID_REQUEST and message in str(err.value)


#: S1's "pick up the box" as perception transferred it: hands on the box sides 15 cm above the floor,
#: 40 cm apart; the demonstrator's feet 73 cm from the box, out of the G1's reach (feet must slide)
_LOW_PICK = (LimbTarget("left_hand", np.array([0.5, 0.022, 0.143]), np.array([-1.0, 0.0, 0.0]), "box"),
             LimbTarget("right_hand", np.array([0.9, 0.009, 0.158]), np.array([1.0, 0.0, 0.0]), "box"),
             LimbTarget("left_foot", np.array([0.579, -0.732, 0.0])),
             LimbTarget("right_foot", np.array([0.834, -0.735, 0.0])))


def test_low_pick_with_sliding_feet_is_reached_whatever_the_target_order(retargeter):
    facing_y = frames.yaw_to_quat(np.pi / 2)
    results = [retargeter.solve(RetargetTarget(order, facing_y, floor_feet_slide=True))
               for order in (_LOW_PICK, _LOW_PICK[::-1])]
    for res in results:
        assert max(res.residuals.values()) <= 0.01
        assert res.within_joint_limits and res.min_self_distance > 0.0
    # the IK's outcome must not depend on the order the caller lists the limbs in
    np.testing.assert_allclose(results[0].qpos, results[1].qpos, atol=1e-9)
