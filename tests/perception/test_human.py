"""Articulated adult body: proportions, two-bone IK, whole-body pose search, collision check."""
from __future__ import annotations

import numpy as np

from lomanip_perception.synthetic.human import (KEYPOINTS, BodyDims, HandTarget, body_capsules, penetration,
                                                random_appearance, solve_pose, two_bone)
from lomanip_perception.synthetic.objects import make_object


def test_adult_proportions():
    d = BodyDims(1.75)
    assert 0.85 < d.hip_height < 0.95 and 0.60 < d.arm + d.palm < 0.72  # leg length, shoulder to palm
    standing = d.hip_height + d.spine + d.shoulder_drop + d.neck + 2 * d.head_r  # floor to the top of the head
    assert abs(standing - 1.75) < 0.05 * 1.75


def test_two_bone_reaches_and_bends_towards_the_pole():
    root, target = np.zeros(3), np.array([0.3, 0.0, -0.3])
    mid, end = two_bone(root, target, 0.3, 0.25, np.array([0.0, 1.0, 0.0]))
    assert np.allclose(end, target) and abs(np.linalg.norm(mid) - 0.3) < 1e-9
    assert abs(np.linalg.norm(end - mid) - 0.25) < 1e-9 and mid[1] > 0
    _, end = two_bone(root, np.array([2.0, 0, 0]), 0.3, 0.25, np.array([0.0, 1.0, 0.0]))
    assert np.linalg.norm(end) < 0.55  # out of reach: stops at full extension


def test_solve_pose_touches_both_sides_of_a_box_without_penetrating_it():
    box = make_object("box", "box", (0.4, 0.35, 0.3), (1, 0, 0, 1), (0, 0, 0.15), 0.0)
    hands = {"left_hand": HandTarget(np.array([0.0, 0.175, 0.2]), np.array([0.0, 1.0, 0.0])),
             "right_hand": HandTarget(np.array([0.0, -0.175, 0.2]), np.array([0.0, -1.0, 0.0]))}
    d = BodyDims(1.75)
    sk, err = solve_pose(d, 0.0, hands, None, [box], 0.0, np.random.default_rng(0))  # facing +x, box ahead
    assert err < 0.01 and penetration(d, sk, [box]) <= 0.01
    for limb, t in hands.items():
        assert np.linalg.norm(sk.points[limb] - (t.contact + d.palm_off * t.normal)) < 0.01
    assert sk.points["left_foot"][2] == 0.0 and sk.points["pelvis"][0] < -0.1  # feet on the floor, behind the box
    assert set(sk.points) == set(KEYPOINTS)
    caps = body_capsules(d, sk, random_appearance(np.random.default_rng(1)))
    assert len(caps) > 15 and all(r > 0 for _, _, _, r, _ in caps)
