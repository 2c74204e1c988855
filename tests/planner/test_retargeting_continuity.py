"""The keyframe IK is continuous in its targets.

S1's pick keyframe (targets as perception gave them in a graph run). Until the seventh session of
2026-11-24 the IK integrated mink's full steps with a switched pelvis-height task; it oscillated
to its iteration cap and a 1e-9 m change of one hand target moved this keyframe by 2.6 rad
(docs/to.md, session 6). It is now a descent with a step acceptance test (``lomanip_planner.ik``).
"""
from __future__ import annotations

import numpy as np
from lomanip_planner.retargeting import LimbTarget, RetargetTarget, Retargeter


def _pick_target(dx: float = 0.0) -> RetargetTarget:
    feet = (LimbTarget("left_foot", np.array([0.3187, 0.1070, 0.0]), object_id="floor"),
            LimbTarget("right_foot", np.array([0.3163, -0.1376, 0.0]), object_id="floor"))
    hands = (LimbTarget("left_hand", np.array([0.7214 + dx, 0.2, 0.2077]), np.array([0.0, 1.0, 0.0]), "box"),
             LimbTarget("right_hand", np.array([0.7149, -0.2, 0.2211]), np.array([0.0, -1.0, 0.0]), "box"))
    prior = {"left_hip_pitch_joint": -2.397, "left_knee_joint": 2.095, "right_hip_pitch_joint": -2.397,
             "right_knee_joint": 2.095, "waist_pitch_joint": 0.977, "left_shoulder_pitch_joint": -0.903,
             "left_elbow_joint": 0.980, "right_shoulder_pitch_joint": -0.906, "right_elbow_joint": 0.988}
    return RetargetTarget(feet + hands, base_orientation_wxyz=np.array([-0.99996, 0.0, 0.0, -0.00912]),
                          joint_prior=prior, pelvis_height_ratio=0.494, floor_feet_slide=True)


def test_pick_keyframe_is_continuous_in_a_hand_target():
    retargeter = Retargeter()
    a = retargeter.solve(_pick_target()).qpos.copy()
    b = retargeter.solve(_pick_target(1e-9)).qpos.copy()
    assert np.max(np.abs(a - b)) < 1e-4
