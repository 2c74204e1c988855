"""The ROS-free plan pipeline: sim scene -> synthetic perception -> retargeted keyframes -> TO problem."""
from __future__ import annotations

import numpy as np
import pytest

from lomanip_planner import offline
from lomanip_to.problem import PlacementGoal, validate_problem


@pytest.fixture(scope="module")
def s2_plan():
    goal = PlacementGoal("box", (0.20, -1.10, 0.475), 0.0)
    prompts = ["pick up the box from the table", "place the box on the trolley", "push the trolley forward"]
    return offline.plan("s2_trolley", prompts, {"box": goal}, solve=False)


def test_s2_prompts_give_feasible_keyframes(s2_plan):
    assert [kf.index for kf in s2_plan.keyframes] == [0, 1, 2]
    for kf in s2_plan.keyframes:
        r = kf.retarget
        assert max(r.residuals.values()) <= 0.01, r.residuals
        assert r.within_joint_limits and r.min_self_distance >= 0.0
        assert max(r.foot_tilt.values()) < 0.02          # feet flat in stance
    # placing: both hands around the goal, above the trolley deck
    hands = np.array([c.position for c in s2_plan.keyframes[1].contacts if c.limb.endswith("hand")])
    assert np.linalg.norm(hands.mean(axis=0)[:2] - [0.20, -1.10]) < 0.1
    # pushing: both hands on the trolley
    assert {c.object_id for c in s2_plan.keyframes[2].contacts if c.limb.endswith("hand")} == {"trolley"}


def test_s2_problem_is_valid_and_ordered(s2_plan):
    validate_problem(s2_plan.problem)
    times = [s2_plan.problem.keyframe_time(k) for k in s2_plan.problem.keyframes]
    assert times == sorted(times) and times[-1] <= s2_plan.problem.duration
    assert s2_plan.problem.placement_goals[0].object_id == "box"
    assert set(s2_plan.timings) == {"perception", "retargeting"}


def test_s2_footsteps_go_round_the_trolley(s2_plan):
    """Walking from the trolley's side (box placed) to its handle, no foothold lands on it."""
    from lomanip_to.route import footprint_of

    trolley = next(o for o in s2_plan.problem.objects if o.id == "trolley")
    fp = footprint_of(trolley, trolley.position, trolley.rpy())
    kf_push = s2_plan.problem.keyframe_time(s2_plan.problem.keyframes[2])
    feet = [c.position for ph in s2_plan.problem.phases if ph.subtask_index == 2 and ph.end <= kf_push
            for limb, c in ph.contacts.items() if limb.endswith("foot")]
    assert feet
    assert min(fp.distance(p) for p in feet) > 0.1
